#pragma once
// Test support for the matcher: PFRGs of polyhedral meshes, rigid partial views, scan-like perturbations.
#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "common/mesh.hpp"
#include "host/pfrg/pfrg.hpp"

namespace fs::test {

using fs::host::Pfrg;
using fs::host::PfrgArc;
using fs::host::PfrgNode;

inline double deg2rad(double d) { return d * std::numbers::pi / 180.0; }

// The PFRG of a closed polyhedral mesh whose polygons are its planar faces: node id = face index, area and
// outward normal (Newell), arcs between faces sharing an edge with border = edge length. No supernode.
inline Pfrg mesh_pfrg(const Mesh& m, double scale = 1.0) {
  Pfrg g;
  g.name = m.name;
  Vec3 center = Vec3::Zero();
  for (const auto& v : m.vertices) center += v;
  center /= static_cast<double>(m.vertices.size());
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::vector<int>> edges;
  for (std::size_t f = 0; f < m.faces.size(); ++f) {
    const auto& poly = m.faces[f];
    Vec3 nsum = Vec3::Zero(), c = Vec3::Zero();
    for (std::size_t k = 0; k < poly.size(); ++k) {
      const Vec3& a = m.vertices[poly[k]];
      const Vec3& b = m.vertices[poly[(k + 1) % poly.size()]];
      nsum += a.cross(b);
      c += a;
      auto e = std::minmax(poly[k], poly[(k + 1) % poly.size()]);
      edges[{e.first, e.second}].push_back(static_cast<int>(f));
    }
    c /= static_cast<double>(poly.size());
    PfrgNode n;
    n.id = static_cast<int>(f);
    n.area = 0.5 * nsum.norm() * scale * scale;
    n.normal = nsum.normalized();
    if (n.normal.dot(c - center) < 0) n.normal = -n.normal;
    g.nodes.push_back(n);
  }
  std::map<std::pair<int, int>, double> border;
  for (const auto& [e, fs] : edges) {
    if (fs.size() != 2 || fs[0] == fs[1]) continue;
    const double len = (m.vertices[e.first] - m.vertices[e.second]).norm() * scale;
    border[std::minmax(fs[0], fs[1])] += len;
  }
  for (const auto& [ab, len] : border) g.arcs.push_back(PfrgArc{ab.first, ab.second, len});
  return g;
}

// What a sensor looking along view_dir sees of the model rotated by R: visible faces ((R n) . -view >
// min_cos) with rotated normals and the same ids, arcs among them, and a supernode (id 1000) bordering every
// visible face that has an invisible neighbour.
inline Pfrg rigid_view(const Pfrg& model, const Mat3& R, const Vec3& view_dir, double min_cos = 0.05) {
  Pfrg v;
  v.name = model.name + "_view";
  const Vec3 obs = -view_dir.normalized();
  std::set<int> vis;
  for (const auto& n : model.nodes) {
    if ((R * n.normal).dot(obs) > min_cos) {
      PfrgNode c = n;
      c.normal = R * n.normal;
      v.nodes.push_back(c);
      vis.insert(n.id);
    }
  }
  std::map<int, double> super;
  for (const auto& a : model.arcs) {
    const bool va = vis.count(a.a) > 0, vb = vis.count(a.b) > 0;
    if (va && vb)
      v.arcs.push_back(a);
    else if (va)
      super[a.a] += a.border;
    else if (vb)
      super[a.b] += a.border;
  }
  if (!super.empty()) {
    PfrgNode sn;
    sn.id = 1000;
    sn.supernode = true;
    v.nodes.push_back(sn);
    for (const auto& [id, b] : super) v.arcs.push_back(PfrgArc{id, 1000, b});
  }
  v.observer = obs;
  v.has_observer = true;
  return v;
}

inline Mat3 random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> nd;
  Eigen::Quaterniond q(nd(rng), nd(rng), nd(rng), nd(rng));
  q.normalize();
  return q.toRotationMatrix();
}

inline Vec3 tilt(const Vec3& n, double max_deg, std::mt19937& rng) {
  std::normal_distribution<double> nd;
  Vec3 axis(nd(rng), nd(rng), nd(rng));
  axis = axis.cross(n);
  if (axis.norm() < 1e-9) return n;
  std::uniform_real_distribution<double> ang(-max_deg, max_deg);
  return Eigen::AngleAxisd(deg2rad(ang(rng)), axis.normalized()) * n;
}

inline std::vector<int> real_ids(const Pfrg& g) {
  std::vector<int> ids;
  for (const auto& n : g.nodes)
    if (!n.supernode) ids.push_back(n.id);
  return ids;
}

struct Perturbation {
  double normal_deg = 3.0;
  double area_rel = 0.15;
  bool split = true;        // one face split in two (ids 2000, 2001 replace it)
  bool spurious = true;     // one spurious face (id 3000) attached to one visible face
  bool missing_arc = true;  // one arc between two visible faces removed
};

// Scan-like perturbation of a view. Returns the id of the split face (-1 if none).
inline int perturb(Pfrg& v, const Perturbation& p, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (auto& n : v.nodes) {
    if (n.supernode) continue;
    n.normal = tilt(n.normal, p.normal_deg, rng);
    n.area *= 1.0 + p.area_rel * u(rng);
  }
  // Missing arc: among arcs between two real faces, drop one whose removal keeps both faces with a real arc.
  if (p.missing_arc) {
    std::map<int, int> deg;
    for (const auto& a : v.arcs)
      if (!v.find(a.a)->supernode && !v.find(a.b)->supernode) {
        ++deg[a.a];
        ++deg[a.b];
      }
    for (std::size_t i = 0; i < v.arcs.size(); ++i) {
      const auto& a = v.arcs[i];
      if (v.find(a.a)->supernode || v.find(a.b)->supernode) continue;
      if (deg[a.a] >= 3 && deg[a.b] >= 3) {
        v.arcs.erase(v.arcs.begin() + static_cast<long>(i));
        break;
      }
    }
  }
  int split_id = -1;
  if (p.split) {
    // Split the largest real face into two (60 / 40) with the same normal (+noise); arcs alternate.
    std::size_t best = 0;
    for (std::size_t i = 0; i < v.nodes.size(); ++i)
      if (!v.nodes[i].supernode && v.nodes[i].area > v.nodes[best].area) best = i;
    PfrgNode a = v.nodes[best], b = v.nodes[best];
    split_id = a.id;
    a.id = 2000;
    b.id = 2001;
    a.area *= 0.6;
    b.area *= 0.4;
    b.normal = tilt(b.normal, 1.0, rng);
    v.nodes.erase(v.nodes.begin() + static_cast<long>(best));
    v.nodes.push_back(a);
    v.nodes.push_back(b);
    int k = 0;
    std::vector<PfrgArc> arcs;
    for (auto arc : v.arcs) {
      if (arc.a == split_id || arc.b == split_id) {
        const int nid = (k++ % 2 == 0) ? 2000 : 2001;
        if (arc.a == split_id)
          arc.a = nid;
        else
          arc.b = nid;
      }
      arcs.push_back(arc);
    }
    arcs.push_back(PfrgArc{2000, 2001, 10.0});
    v.arcs = arcs;
  }
  if (p.spurious) {
    PfrgNode s;
    s.id = 3000;
    std::normal_distribution<double> nd;
    s.normal = Vec3(nd(rng), nd(rng), nd(rng)).normalized();
    if (v.has_observer && s.normal.dot(v.observer) < 0) s.normal = -s.normal;
    double total = 0;
    for (const auto& n : v.nodes) total += n.area;
    s.area = 0.05 * total;
    for (const auto& n : v.nodes)
      if (!n.supernode && n.id != 2000 && n.id != 2001) {
        v.arcs.push_back(PfrgArc{n.id, 3000, 5.0});
        break;
      }
    v.nodes.push_back(s);
  }
  return split_id;
}

// A truncated square pyramid (PYRAM2-like): base side `b` at z = 0, top side `t` at height h. Faces: 0 base,
// 1 top, 2..5 sides.
inline Mesh truncated_pyramid(double b = 100, double t = 60, double h = 40) {
  Mesh m;
  m.name = "pyram2";
  const double B = b / 2, T = t / 2;
  m.vertices = {{-B, -B, 0}, {B, -B, 0}, {B, B, 0}, {-B, B, 0},
                {-T, -T, h}, {T, -T, h}, {T, T, h}, {-T, T, h}};
  m.faces = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
  return m;
}

inline Mesh box(double x, double y, double z, const char* name = "cube") {
  Mesh m;
  m.name = name;
  m.vertices = {{0, 0, 0}, {x, 0, 0}, {x, y, 0}, {0, y, 0}, {0, 0, z}, {x, 0, z}, {x, y, z}, {0, y, z}};
  m.faces = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
  return m;
}

}  // namespace fs::test
