// Near symmetries of a model (near_symmetry.hpp): candidate motions from a reference pair of adjacent faces
// onto every congruent adjacent pair, each scored by the area of the faces it maps onto faces.
#include "host/recognize/near_symmetry.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace fs::host::rec {

namespace {

Mat3 frame(const Vec3& a, const Vec3& b) {
  Mat3 F;
  const Vec3 u = (b - b.dot(a) * a).normalized();
  F.col(0) = a;
  F.col(1) = u;
  F.col(2) = a.cross(u);
  return F;
}

struct Analysis {
  const Model& model;
  double len_tol = 0, area_tol = 0, normal_tol = 0;
  std::vector<std::vector<int>> adj;        // face neighbours
  std::vector<std::vector<double>> border;  // border length, parallel to adj
  std::vector<int> cls;                     // congruence class (same area and perimeter) of each face
  std::vector<std::vector<int>> members;    // faces of each class
  std::vector<int> by_area;                 // faces, largest first

  explicit Analysis(const Model& m, double tol) : model(m) {
    const std::size_t n = m.faces.size();
    double max_area = 0;
    for (const ModelFace& f : m.faces) max_area = std::max(max_area, f.area);
    len_tol = tol * std::max(m.bounding_radius, 1e-300);
    area_tol = tol * max_area;
    normal_tol = tol;
    adj.resize(n);
    border.resize(n);
    for (const PfrgArc& a : m.graph.arcs) {
      if (a.a < 0 || a.b < 0 || static_cast<std::size_t>(a.a) >= n || static_cast<std::size_t>(a.b) >= n)
        continue;
      adj[static_cast<std::size_t>(a.a)].push_back(a.b);
      border[static_cast<std::size_t>(a.a)].push_back(a.border);
      adj[static_cast<std::size_t>(a.b)].push_back(a.a);
      border[static_cast<std::size_t>(a.b)].push_back(a.border);
    }
    cls.assign(n, -1);
    for (std::size_t i = 0; i < n; ++i) {
      if (cls[i] >= 0) continue;
      cls[i] = static_cast<int>(members.size());
      members.push_back({static_cast<int>(i)});
      for (std::size_t j = i + 1; j < n; ++j)
        if (cls[j] < 0 && congruent(i, j)) {
          cls[j] = cls[i];
          members.back().push_back(static_cast<int>(j));
        }
    }
    by_area.resize(n);
    for (std::size_t i = 0; i < n; ++i) by_area[i] = static_cast<int>(i);
    std::stable_sort(by_area.begin(), by_area.end(), [&](int a, int b) {
      return m.faces[static_cast<std::size_t>(a)].area > m.faces[static_cast<std::size_t>(b)].area;
    });
  }
  bool congruent(std::size_t i, std::size_t j) const {
    const ModelFace& a = model.faces[i];
    const ModelFace& b = model.faces[j];
    return std::abs(a.area - b.area) <= area_tol && std::abs(a.perimeter - b.perimeter) <= len_tol;
  }
  double border_of(std::size_t a, int b) const {
    for (std::size_t k = 0; k < adj[a].size(); ++k)
      if (adj[a][k] == b) return border[a][k];
    return -1.0;
  }
  // The face of the same class that face i lands on under x -> S x + u, or -1.
  int image(std::size_t i, const Mat3& S, const Vec3& u) const {
    const ModelFace& f = model.faces[i];
    const Vec3 n = S * f.normal;
    const Vec3 c = S * f.centroid + u;
    for (int j : members[static_cast<std::size_t>(cls[i])]) {
      const ModelFace& g = model.faces[static_cast<std::size_t>(j)];
      if ((n - g.normal).norm() <= normal_tol && (c - g.centroid).norm() <= len_tol) return j;
    }
    return -1;
  }
  // Fills T.preimage and T.share; false as soon as more than (1 - min_share) of the area is left unmapped.
  bool score(NearSymmetry& T, double min_share) const {
    const std::size_t n = model.faces.size();
    const double allowed = (1.0 - min_share) * model.total_area;
    T.preimage.assign(n, -1);
    double lost = 0.0;
    for (int i : by_area) {
      const int j = image(static_cast<std::size_t>(i), T.S, T.u);
      if (j < 0 || T.preimage[static_cast<std::size_t>(j)] >= 0) {
        lost += model.faces[static_cast<std::size_t>(i)].area;
        if (lost > allowed) return false;
        continue;
      }
      T.preimage[static_cast<std::size_t>(j)] = i;
    }
    T.share = model.total_area > 0 ? 1.0 - lost / model.total_area : 0.0;
    return true;
  }
  // T and a kept K place the model equivalently: T = K composed with a symmetry G about the centre.
  bool equivalent(const NearSymmetry& T, const NearSymmetry& K) const {
    if ((K.S - T.S).norm() <= 3 * normal_tol && (K.u - T.u).norm() <= 3 * len_tol) return true;
    for (const Mat3& G : model.symmetries) {
      if ((K.S * G - T.S).norm() > 3 * normal_tol) continue;
      const Vec3 u = K.u + K.S * (model.center - G * model.center);
      if ((u - T.u).norm() <= 3 * len_tol) return true;
    }
    return false;
  }
};

// Up to `count` faces spread over the model: the largest face, then each time the face farthest from those
// chosen.
std::vector<int> seed_faces(const Model& m, const Analysis& a, int count) {
  std::vector<int> seeds;
  const std::size_t n = m.faces.size();
  std::vector<double> dist(n, std::numeric_limits<double>::infinity());
  int next = a.by_area.front();
  while (static_cast<int>(seeds.size()) < count && next >= 0) {
    seeds.push_back(next);
    const Vec3& c = m.faces[static_cast<std::size_t>(next)].centroid;
    next = -1;
    double far = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      dist[i] = std::min(dist[i], (m.faces[i].centroid - c).norm());
      if (dist[i] > far) far = dist[i], next = static_cast<int>(i);
    }
  }
  return seeds;
}

}  // namespace

std::vector<NearSymmetry> near_symmetries(const Model& model, const NearSymmetryParams& p) {
  std::vector<NearSymmetry> out;
  const std::size_t n = model.faces.size();
  if (n < 4 || model.total_area <= 0 || p.max_count <= 0) return out;
  const Analysis a(model, p.tolerance);
  NearSymmetry T;
  for (int f0 : seed_faces(model, a, p.seeds)) {
    const auto s0 = static_cast<std::size_t>(f0);
    const Vec3& n0 = model.faces[s0].normal;
    // Its neighbour of the rarest class, not parallel to it.
    int f1 = -1;
    for (int j : a.adj[s0]) {
      if (std::abs(model.faces[static_cast<std::size_t>(j)].normal.dot(n0)) > 1 - 1e-6) continue;
      if (f1 < 0 || a.members[static_cast<std::size_t>(a.cls[static_cast<std::size_t>(j)])].size() <
                        a.members[static_cast<std::size_t>(a.cls[static_cast<std::size_t>(f1)])].size())
        f1 = j;
    }
    if (f1 < 0) continue;
    const auto s1 = static_cast<std::size_t>(f1);
    const Mat3 Ff = frame(n0, model.faces[s1].normal);
    const double cos01 = n0.dot(model.faces[s1].normal);
    const double b01 = a.border_of(s0, f1);
    for (int g0 : a.members[static_cast<std::size_t>(a.cls[s0])]) {
      const auto t0 = static_cast<std::size_t>(g0);
      for (std::size_t k = 0; k < a.adj[t0].size(); ++k) {
        const int g1 = a.adj[t0][k];
        const auto t1 = static_cast<std::size_t>(g1);
        if (a.cls[t1] != a.cls[s1] || std::abs(a.border[t0][k] - b01) > a.len_tol) continue;
        const Vec3& m0 = model.faces[t0].normal;
        const Vec3& m1 = model.faces[t1].normal;
        if (std::abs(m0.dot(m1) - cos01) > p.tolerance) continue;
        T.S = frame(m0, m1) * Ff.transpose();
        T.u = model.faces[t0].centroid - T.S * model.faces[s0].centroid;
        if ((T.S * model.faces[s1].centroid + T.u - model.faces[t1].centroid).norm() > a.len_tol) continue;
        if (!a.score(T, p.min_share)) continue;
        // Every face mapped: a symmetry (or the identity), not a look-alike placement.
        if (std::find(T.preimage.begin(), T.preimage.end(), -1) == T.preimage.end()) continue;
        bool known = false;
        for (const NearSymmetry& K : out) known = known || a.equivalent(T, K);
        if (known) continue;
        out.push_back(T);
        if (static_cast<int>(out.size()) >= p.max_count) return out;
      }
    }
  }
  return out;
}

}  // namespace fs::host::rec
