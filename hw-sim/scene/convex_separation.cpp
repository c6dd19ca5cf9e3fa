#include "hw-sim/scene/convex_separation.hpp"

#include <algorithm>
#include <cmath>

namespace fs::sim {

namespace {

constexpr double kSameDirection = 1e-6;  // rad

// Adds unit direction d unless it (or -d) is already there; zero vectors are dropped.
void add_direction(std::vector<Vec3>& list, const Vec3& v) {
  const double len = v.norm();
  if (!(len > 1e-12)) return;
  const Vec3 d = v / len;
  for (const auto& e : list)
    if (e.cross(d).norm() < kSameDirection) return;
  list.push_back(d);
}

void add_polygon(ConvexShape& s, const std::vector<Vec3>& polygon) {
  Vec3 n = Vec3::Zero();  // Newell
  for (std::size_t k = 0; k < polygon.size(); ++k) {
    const Vec3& a = polygon[k];
    const Vec3& b = polygon[(k + 1) % polygon.size()];
    n += a.cross(b);
    add_direction(s.edges, b - a);
  }
  add_direction(s.normals, n);
}

void extent(const std::vector<Vec3>& vertices, const Vec3& d, double& lo, double& hi) {
  lo = 1e300, hi = -1e300;
  for (const auto& v : vertices) {
    const double p = d.dot(v);
    lo = std::min(lo, p);
    hi = std::max(hi, p);
  }
}

}  // namespace

ConvexShape ConvexShape::of(const SceneObject& object) {
  ConvexShape s;
  for (const auto& f : object.faces) {
    for (const auto& x : f.polygon) s.vertices.push_back(x);
    add_polygon(s, f.polygon);
  }
  return s;
}

ConvexShape ConvexShape::of(const Mesh& mesh, const Mat3& R, const Vec3& t) {
  ConvexShape s;
  s.vertices.reserve(mesh.vertices.size());
  for (const auto& v : mesh.vertices) s.vertices.push_back(R * v + t);
  std::vector<Vec3> polygon;
  for (const auto& f : mesh.faces) {
    polygon.clear();
    for (auto i : f) polygon.push_back(s.vertices.at(i));
    add_polygon(s, polygon);
  }
  return s;
}

PairSeparation::PairSeparation(const ConvexShape& a, const ConvexShape& b) {
  auto add = [&](const Vec3& d) {
    Axis x{d, 0, 0, 0, 0};
    extent(a.vertices, d, x.a_lo, x.a_hi);
    extent(b.vertices, d, x.b_lo, x.b_hi);
    axes_.push_back(x);
  };
  axes_.reserve(a.normals.size() + b.normals.size() + a.edges.size() * b.edges.size());
  for (const auto& n : a.normals) add(n);
  for (const auto& n : b.normals) add(n);
  for (const auto& ea : a.edges)
    for (const auto& eb : b.edges) {
      const Vec3 c = ea.cross(eb);
      const double len = c.norm();
      if (len > 1e-9) add(c / len);  // parallel edges give no axis of their own
    }
}

double PairSeparation::at(const Vec3& t) const {
  double best = -1e300;
  for (const auto& x : axes_) {
    const double s = x.d.dot(t);
    best = std::max(best, std::max(x.b_lo - (x.a_hi + s), (x.a_lo + s) - x.b_hi));
  }
  return best;
}

bool PairSeparation::at_least(const Vec3& t, double gap) const {
  for (const auto& x : axes_) {
    const double s = x.d.dot(t);
    if (x.b_lo - (x.a_hi + s) >= gap || (x.a_lo + s) - x.b_hi >= gap) return true;
  }
  return false;
}

double separation(const ConvexShape& a, const ConvexShape& b) {
  return PairSeparation(a, b).at(Vec3::Zero());
}

}  // namespace fs::sim
