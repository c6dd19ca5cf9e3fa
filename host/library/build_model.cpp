// build_model: polygon mesh -> planar faces + adjacency (thesis ch. 4.1.2, "CAD description to reference
// model"). Steps: scale + weld vertices, drop degenerate facets, pair facet edges (radially around
// non-manifold edges), make the winding consistent and outward, merge coplanar adjacent facets into faces,
// trace face boundary loops, accumulate shared edge lengths into arcs.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <numbers>
#include <queue>
#include <unordered_map>
#include <utility>

#include <fmt/format.h>

#include "common/error.hpp"
#include "host/library/model.hpp"

namespace fs::host {
namespace {

struct Facet {
  std::vector<std::uint32_t> v;  // welded vertex indices
  Vec3 newell = Vec3::Zero();    // 2 * area * unit normal
  std::uint32_t first_he = 0;    // index of its first half-edge
  std::uint32_t mesh_index = 0;  // index in Mesh::faces (for messages)
};

std::string vtx(const Vec3& p) { return fmt::format("({:.6g}, {:.6g}, {:.6g})", p.x(), p.y(), p.z()); }

Vec3 newell_of(const std::vector<std::uint32_t>& v, const std::vector<Vec3>& P) {
  Vec3 n = Vec3::Zero();
  for (std::size_t i = 0; i < v.size(); ++i) n += P[v[i]].cross(P[v[(i + 1) % v.size()]]);
  return n;
}

Vec3 facet_centroid(const Facet& f, const std::vector<Vec3>& P) {
  Vec3 c = Vec3::Zero();
  for (auto i : f.v) c += P[i];
  return c / static_cast<double>(f.v.size());
}

// Vertices of the scaled mesh merged when closer than tol (grid hashing, 27-cell neighbourhood).
// Keys are taken relative to lo with a cell of at least 1e-12 * diag, so they stay far inside int64.
std::vector<std::uint32_t> weld(const std::vector<Vec3>& P, const Vec3& lo, double diag, double tol,
                                std::vector<Vec3>& out) {
  struct KeyHash {
    std::size_t operator()(const std::array<std::int64_t, 3>& k) const {
      return static_cast<std::size_t>(k[0] * 73856093LL ^ k[1] * 19349663LL ^ k[2] * 83492791LL);
    }
  };
  std::unordered_map<std::array<std::int64_t, 3>, std::vector<std::uint32_t>, KeyHash> grid;
  std::vector<std::uint32_t> map(P.size());
  const double cell = std::max(tol, 1e-12 * diag);
  for (std::size_t i = 0; i < P.size(); ++i) {
    const Vec3 q = (P[i] - lo) / cell;
    const std::array<std::int64_t, 3> k{static_cast<std::int64_t>(std::floor(q.x())),
                                        static_cast<std::int64_t>(std::floor(q.y())),
                                        static_cast<std::int64_t>(std::floor(q.z()))};
    std::int64_t found = -1;
    for (int dx = -1; dx <= 1 && found < 0; ++dx)
      for (int dy = -1; dy <= 1 && found < 0; ++dy)
        for (int dz = -1; dz <= 1 && found < 0; ++dz) {
          auto it = grid.find({k[0] + dx, k[1] + dy, k[2] + dz});
          if (it == grid.end()) continue;
          for (auto r : it->second)
            if ((out[r] - P[i]).norm() <= tol) {
              found = r;
              break;
            }
        }
    if (found >= 0) {
      map[i] = static_cast<std::uint32_t>(found);
    } else {
      map[i] = static_cast<std::uint32_t>(out.size());
      grid[k].push_back(map[i]);
      out.push_back(P[i]);
    }
  }
  return map;
}

struct HalfEdges {
  std::vector<std::uint32_t> facet;   // owning facet
  std::vector<std::int64_t> partner;  // paired half-edge or -1 (boundary)
  bool nonmanifold = false;
};

// Pairs every half-edge a->b with one b->a (or a->b when the winding is inconsistent) of another facet.
// Around an edge shared by more than two facets the pairing follows the solid: each facet is paired with its
// angular neighbour on its material side (needs outward winding there).
HalfEdges pair_edges(std::vector<Facet>& facets, const std::vector<Vec3>& P, const std::string& src,
                     bool allow_open, std::size_t& boundary_edges) {
  HalfEdges he;
  struct Rec {
    std::uint64_t key;
    std::uint32_t h;
  };
  std::vector<Rec> recs;
  std::uint32_t n = 0;
  for (std::uint32_t f = 0; f < facets.size(); ++f) {
    facets[f].first_he = n;
    const auto& v = facets[f].v;
    for (std::size_t i = 0; i < v.size(); ++i, ++n) {
      const std::uint32_t a = v[i], b = v[(i + 1) % v.size()];
      recs.push_back({(std::uint64_t{std::min(a, b)} << 32) | std::max(a, b), n});
      he.facet.push_back(f);
    }
  }
  he.partner.assign(n, -1);
  auto ends = [&](std::uint32_t h, std::uint32_t& a, std::uint32_t& b) {
    const Facet& f = facets[he.facet[h]];
    const std::size_t i = h - f.first_he;
    a = f.v[i];
    b = f.v[(i + 1) % f.v.size()];
  };
  std::sort(recs.begin(), recs.end(),
            [](const Rec& x, const Rec& y) { return x.key != y.key ? x.key < y.key : x.h < y.h; });
  boundary_edges = 0;
  for (std::size_t i = 0; i < recs.size();) {
    std::size_t j = i;
    while (j < recs.size() && recs[j].key == recs[i].key) ++j;
    const std::size_t k = j - i;
    const std::uint32_t lo = static_cast<std::uint32_t>(recs[i].key >> 32);
    const std::uint32_t hi = static_cast<std::uint32_t>(recs[i].key & 0xffffffffu);
    if (k == 1) {
      ++boundary_edges;
      if (!allow_open)
        throw Error(
            fmt::format("{}: open mesh: the edge {} - {} belongs to one facet only (facet {}); "
                        "the mesh must be closed (or use the allow-open option)",
                        src, vtx(P[lo]), vtx(P[hi]), facets[he.facet[recs[i].h]].mesh_index));
    } else if (k == 2) {
      if (he.facet[recs[i].h] == he.facet[recs[i + 1].h])
        throw Error(fmt::format("{}: facet {} uses the edge {} - {} twice", src,
                                facets[he.facet[recs[i].h]].mesh_index, vtx(P[lo]), vtx(P[hi])));
      he.partner[recs[i].h] = recs[i + 1].h;
      he.partner[recs[i + 1].h] = recs[i].h;
    } else {
      he.nonmanifold = true;
      const auto fail = [&](const char* why) {
        return Error(fmt::format("{}: non-manifold edge {} - {} shared by {} facets ({})", src, vtx(P[lo]),
                                 vtx(P[hi]), k, why));
      };
      if (k % 2) throw fail("odd number of facets");
      const Vec3 t = (P[hi] - P[lo]).normalized();
      const Vec3 b1 = t.unitOrthogonal(), b2 = t.cross(b1);
      struct Around {
        double theta;
        std::uint32_t h;
        bool material_up;
        bool forward;
      };
      std::vector<Around> around;
      for (std::size_t r = i; r < j; ++r) {
        const std::uint32_t h = recs[r].h;
        const Facet& f = facets[he.facet[h]];
        Vec3 w = facet_centroid(f, P) - P[lo];
        w -= w.dot(t) * t;
        if (w.norm() <= 0) throw fail("degenerate facet");
        w.normalize();
        std::uint32_t a = 0, b = 0;
        ends(h, a, b);
        const Vec3 n = f.newell.normalized();
        around.push_back({std::atan2(w.dot(b2), w.dot(b1)), h, (-n).dot(t.cross(w)) > 0, a == lo});
      }
      std::sort(around.begin(), around.end(),
                [](const Around& x, const Around& y) { return x.theta < y.theta; });
      for (std::size_t r = 0; r < k; ++r) {
        const std::size_t q = around[r].material_up ? (r + 1) % k : (r + k - 1) % k;
        const std::size_t back = around[q].material_up ? (q + 1) % k : (q + k - 1) % k;
        if (back != r || around[q].forward == around[r].forward) throw fail("inconsistent winding around it");
        he.partner[around[r].h] = around[q].h;
      }
    }
    i = j;
  }
  return he;
}

double signed_volume6(const std::vector<Facet>& facets, const std::vector<Vec3>& P, const Vec3& origin) {
  double v = 0;
  for (const auto& f : facets)
    for (std::size_t i = 1; i + 1 < f.v.size(); ++i)
      v += (P[f.v[0]] - origin).dot((P[f.v[i]] - origin).cross(P[f.v[i + 1]] - origin));
  return v;
}

void flip(Facet& f) {
  std::reverse(f.v.begin(), f.v.end());
  f.newell = -f.newell;
}

// Removes vertices where the loop goes straight on.
std::vector<Vec3> simplify_loop(const std::vector<Vec3>& loop, double tol) {
  std::vector<Vec3> out = loop;
  bool changed = true;
  while (changed && out.size() > 3) {
    changed = false;
    for (std::size_t i = 0; i < out.size() && out.size() > 3; ++i) {
      const Vec3& a = out[(i + out.size() - 1) % out.size()];
      const Vec3& b = out[i];
      const Vec3& c = out[(i + 1) % out.size()];
      const Vec3 ac = c - a;
      const double len = ac.norm();
      const double dist = len > 0 ? (b - a).cross(ac).norm() / len : (b - a).norm();
      if (dist <= tol && (b - a).dot(ac) >= 0 && (c - b).dot(ac) >= 0) {
        out.erase(out.begin() + static_cast<std::ptrdiff_t>(i));
        changed = true;
        --i;
      }
    }
  }
  return out;
}

}  // namespace

double Model::total_border() const {
  double s = 0;
  for (const auto& a : graph.arcs) s += a.border;
  return s;
}

Model build_model(const Mesh& mesh, const BuildOptions& options, const std::string& source) {
  const std::string src = !source.empty() ? source : mesh.name.empty() ? std::string("mesh") : mesh.name;
  if (mesh.vertices.empty() || mesh.faces.empty())
    throw Error(
        fmt::format("{}: empty mesh ({} vertices, {} faces)", src, mesh.vertices.size(), mesh.faces.size()));
  if (!(options.scale > 0) || !std::isfinite(options.scale))
    throw Error(fmt::format("{}: scale must be a positive number (got {})", src, options.scale));

  std::vector<Vec3> scaled(mesh.vertices.size());
  Vec3 lo = Vec3::Constant(INFINITY), hi = Vec3::Constant(-INFINITY);
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    if (!mesh.vertices[i].allFinite()) throw Error(fmt::format("{}: vertex {} is not finite", src, i));
    scaled[i] = mesh.vertices[i] * options.scale;
    lo = lo.cwiseMin(scaled[i]);
    hi = hi.cwiseMax(scaled[i]);
  }
  const double diag = (hi - lo).norm();
  if (!(diag > 0)) throw Error(fmt::format("{}: all vertices coincide", src));
  if (!(diag < 1e100) || diag < 1e-100 || lo.cwiseAbs().maxCoeff() > 1e100 ||
      hi.cwiseAbs().maxCoeff() > 1e100)
    throw Error(fmt::format("{}: coordinates out of range (bounding-box diagonal {:g})", src, diag));
  if (!(options.weld_tolerance >= 0) || !(options.merge_angle_deg >= 0))
    throw Error(fmt::format("{}: weld tolerance and merge angle must be >= 0", src));
  std::vector<Vec3> P;
  const std::vector<std::uint32_t> wmap = weld(scaled, lo, diag, options.weld_tolerance * diag, P);

  // Facets: welded, consecutive duplicates removed, zero-area ones dropped.
  std::vector<Facet> facets;
  const double min_area2 = 1e-14 * diag * diag;
  for (std::size_t fi = 0; fi < mesh.faces.size(); ++fi) {
    Facet f;
    f.mesh_index = static_cast<std::uint32_t>(fi);
    for (auto idx : mesh.faces[fi]) {
      if (idx >= mesh.vertices.size())
        throw Error(fmt::format("{}: face {}: vertex index {} out of range ({} vertices)", src, fi, idx,
                                mesh.vertices.size()));
      const std::uint32_t w = wmap[idx];
      if (f.v.empty() || f.v.back() != w) f.v.push_back(w);
    }
    while (f.v.size() > 1 && f.v.front() == f.v.back()) f.v.pop_back();
    if (f.v.size() < 3) continue;
    f.newell = newell_of(f.v, P);
    if (f.newell.norm() <= min_area2) continue;
    facets.push_back(std::move(f));
  }
  if (facets.size() < (options.allow_open ? 1u : 4u))
    throw Error(fmt::format("{}: only {} non-degenerate facets; a closed polyhedron needs at least 4", src,
                            facets.size()));

  Vec3 mean = Vec3::Zero();
  for (const auto& p : P) mean += p;
  mean /= static_cast<double>(P.size());

  std::size_t boundary = 0;
  HalfEdges he = pair_edges(facets, P, src, options.allow_open, boundary);
  if (he.nonmanifold && signed_volume6(facets, P, mean) < 0) {
    // Radial pairing needs outward winding: turn an inward-wound mesh around and pair again.
    for (auto& f : facets) flip(f);
    he = pair_edges(facets, P, src, options.allow_open, boundary);
  }

  // Consistent winding per connected component (breadth-first), then outward (positive volume).
  std::vector<int> flipped(facets.size(), -1);
  std::vector<int> component(facets.size(), -1);
  int components = 0;
  for (std::uint32_t seed = 0; seed < facets.size(); ++seed) {
    if (flipped[seed] >= 0) continue;
    std::vector<std::uint32_t> members{seed};
    flipped[seed] = 0;
    component[seed] = components;
    for (std::size_t q = 0; q < members.size(); ++q) {
      const std::uint32_t f = members[q];
      const auto& v = facets[f].v;
      for (std::size_t i = 0; i < v.size(); ++i) {
        const std::int64_t p = he.partner[facets[f].first_he + i];
        if (p < 0) continue;
        const std::uint32_t g = he.facet[static_cast<std::size_t>(p)];
        const std::size_t j = static_cast<std::size_t>(p) - facets[g].first_he;
        const bool same_dir = facets[g].v[j] == v[i];
        const int want = flipped[f] ^ static_cast<int>(same_dir);
        if (flipped[g] < 0) {
          flipped[g] = want;
          component[g] = components;
          members.push_back(g);
        } else if (flipped[g] != want) {
          throw Error(fmt::format("{}: non-orientable surface (facets {} and {} around the edge {} - {})",
                                  src, facets[f].mesh_index, facets[g].mesh_index, vtx(P[v[i]]),
                                  vtx(P[v[(i + 1) % v.size()]])));
        }
      }
    }
    ++components;
  }
  bool any_flip = false;
  for (std::size_t f = 0; f < facets.size(); ++f)
    if (flipped[f]) {
      flip(facets[f]);
      any_flip = true;
    }
  for (int c = 0; c < components; ++c) {
    std::vector<Facet> part;
    std::vector<std::size_t> idx;
    for (std::size_t f = 0; f < facets.size(); ++f)
      if (component[f] == c) {
        part.push_back(facets[f]);
        idx.push_back(f);
      }
    Vec3 origin = Vec3::Zero();
    double w = 0;
    for (const auto& f : part) {
      origin += facet_centroid(f, P) * f.newell.norm();
      w += f.newell.norm();
    }
    origin /= w;
    if (signed_volume6(part, P, origin) < 0) {
      for (auto f : idx) flip(facets[f]);
      any_flip = true;
    }
  }
  if (any_flip) he = pair_edges(facets, P, src, options.allow_open, boundary);

  // Merge coplanar adjacent facets: region growing from the largest facet, against the facet neighbour and
  // the region's mean normal (so that slowly curving tessellations do not collapse into one face).
  const double cos_tol = std::cos(options.merge_angle_deg * std::numbers::pi / 180.0);
  std::vector<std::uint32_t> order(facets.size());
  for (std::uint32_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](auto a, auto b) { return facets[a].newell.norm() > facets[b].newell.norm(); });
  std::vector<int> region(facets.size(), -1);
  std::vector<Vec3> region_newell;
  for (auto seed : order) {
    if (region[seed] >= 0) continue;
    const int r = static_cast<int>(region_newell.size());
    region_newell.push_back(facets[seed].newell);
    region[seed] = r;
    std::vector<std::uint32_t> queue{seed};
    for (std::size_t q = 0; q < queue.size(); ++q) {
      const std::uint32_t f = queue[q];
      const Vec3 nf = facets[f].newell.normalized();
      for (std::size_t i = 0; i < facets[f].v.size(); ++i) {
        const std::int64_t p = he.partner[facets[f].first_he + i];
        if (p < 0) continue;
        const std::uint32_t g = he.facet[static_cast<std::size_t>(p)];
        if (region[g] >= 0) continue;
        const Vec3 ng = facets[g].newell.normalized();
        if (ng.dot(nf) < cos_tol || ng.dot(region_newell[r].normalized()) < cos_tol) continue;
        region[g] = r;
        region_newell[r] += facets[g].newell;
        queue.push_back(g);
      }
    }
  }

  Model model;
  model.name = mesh.name;
  model.open = boundary > 0;
  const std::size_t nreg = region_newell.size();
  model.faces.resize(nreg);
  std::vector<double> weight(nreg, 0.0);
  for (std::size_t f = 0; f < facets.size(); ++f) {
    const auto r = static_cast<std::size_t>(region[f]);
    const auto& v = facets[f].v;
    // Area centroid by a fan of signed triangles.
    const Vec3 n = region_newell[r].normalized();
    for (std::size_t i = 1; i + 1 < v.size(); ++i) {
      const double a = 0.5 * n.dot((P[v[i]] - P[v[0]]).cross(P[v[i + 1]] - P[v[0]]));
      model.faces[r].centroid += a * (P[v[0]] + P[v[i]] + P[v[i + 1]]) / 3.0;
      weight[r] += a;
    }
  }
  for (std::size_t r = 0; r < nreg; ++r) {
    ModelFace& face = model.faces[r];
    face.normal = region_newell[r].normalized();
    face.area = 0.5 * region_newell[r].norm();
    face.centroid = weight[r] != 0 ? Vec3(face.centroid / weight[r]) : face.centroid;
    face.offset = face.normal.dot(face.centroid);
  }

  // Boundary loops of every face: its half-edges whose partner lies in another face (or none).
  std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> border_he(nreg);
  std::map<std::pair<int, int>, double> arc_len;
  for (std::uint32_t f = 0; f < facets.size(); ++f) {
    const auto& v = facets[f].v;
    for (std::size_t i = 0; i < v.size(); ++i) {
      const std::int64_t p = he.partner[facets[f].first_he + i];
      const int rf = region[f];
      const int rg = p < 0 ? -1 : region[he.facet[static_cast<std::size_t>(p)]];
      if (rg == rf) continue;
      const std::uint32_t a = v[i], b = v[(i + 1) % v.size()];
      border_he[static_cast<std::size_t>(rf)].push_back({a, b});
      if (rg >= 0 && rf < rg) arc_len[{rf, rg}] += (P[b] - P[a]).norm();
    }
  }
  const double lin_tol = 1e-9 * diag;
  for (std::size_t r = 0; r < nreg; ++r) {
    auto& edges = border_he[r];
    std::multimap<std::uint32_t, std::size_t> from;
    for (std::size_t e = 0; e < edges.size(); ++e) from.emplace(edges[e].first, e);
    std::vector<bool> used(edges.size(), false);
    for (std::size_t s = 0; s < edges.size(); ++s) {
      if (used[s]) continue;
      std::vector<Vec3> loop;
      std::size_t e = s;
      for (;;) {
        used[e] = true;
        loop.push_back(P[edges[e].first]);
        const std::uint32_t next_v = edges[e].second;
        if (next_v == edges[s].first) break;
        std::size_t next = edges.size();
        for (auto [it, end] = from.equal_range(next_v); it != end; ++it)
          if (!used[it->second]) {
            next = it->second;
            break;
          }
        if (next == edges.size())
          throw Error(fmt::format("{}: the boundary of face {} is not closed at {}", src, r, vtx(P[next_v])));
        e = next;
      }
      loop = simplify_loop(loop, lin_tol);
      for (std::size_t i = 0; i < loop.size(); ++i)
        model.faces[r].perimeter += (loop[(i + 1) % loop.size()] - loop[i]).norm();
      model.faces[r].loops.push_back(std::move(loop));
    }
    // Outer loops (counter-clockwise about the normal) first.
    const Vec3 n = model.faces[r].normal;
    auto signed_area = [&](const std::vector<Vec3>& l) {
      Vec3 s = Vec3::Zero();
      for (std::size_t i = 0; i < l.size(); ++i) s += l[i].cross(l[(i + 1) % l.size()]);
      return 0.5 * n.dot(s);
    };
    std::stable_sort(model.faces[r].loops.begin(), model.faces[r].loops.end(),
                     [&](const auto& a, const auto& b) { return signed_area(a) > signed_area(b); });
  }

  std::vector<PfrgArc> arcs;
  for (const auto& [k, len] : arc_len) arcs.push_back({k.first, k.second, len});
  finish_model(model, std::move(arcs), options);
  return model;
}

}  // namespace fs::host
