#include "hw-sim/scene/cluttered_scene.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <utility>

#include <Eigen/Geometry>

#include "hw-sim/scene/convex_separation.hpp"

namespace fs::sim {

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kAboveTable_mm = 0.5;  // a stacked object's lowest point above the table

// How far p (in the plane of the convex polygon, normal n) lies inside it: the smallest distance to an edge
// line, negative outside.
double inside_depth(const std::vector<Vec3>& polygon, const Vec3& n, const Vec3& p) {
  double lo = 1e300, hi = -1e300;
  for (std::size_t k = 0; k < polygon.size(); ++k) {
    const Vec3& a = polygon[k];
    const Vec3 e = polygon[(k + 1) % polygon.size()] - a;
    const double len = e.norm();
    if (len == 0) continue;
    const double s = n.dot(e.cross(p - a)) / len;
    lo = std::min(lo, s);
    hi = std::max(hi, s);
  }
  if (lo >= 0) return lo;  // either winding
  if (hi <= 0) return -hi;
  return std::min(lo, -hi);
}

// A catalog entry's volume; computed when the catalog left it unset.
double volume_of(const CatalogEntry& e) { return e.volume_mm3 > 0 ? e.volume_mm3 : mesh_volume(e.mesh); }

struct Cluster {
  const std::vector<CatalogEntry>& catalog;
  const RandomSceneOptions& o;
  Prng& rng;
  RandomScene& out;
  std::vector<ConvexShape> shapes;  // per placed object

  double uniform(double a, double b) { return a + (b - a) * rng.uniform(); }
  template <typename T>
  const T& pick(const std::vector<T>& v) {
    return v[rng.below(v.size())];
  }

  void add(int ci, const Mat3& R, const Vec3& t, int face, int support, int support_face) {
    add_object(out.scene, catalog[static_cast<std::size_t>(ci)].mesh, R, t);
    out.catalog_index.push_back(ci);
    out.resting_face.push_back(face);
    out.support.push_back(support);
    out.support_face.push_back(support_face);
    shapes.push_back(ConvexShape::of(out.scene.objects.back()));
  }

  bool in_rect(const ConvexShape& s) const {
    for (const auto& v : s.vertices)
      if (v.x() < o.x_min || v.x() > o.x_max || v.y() < o.y_min || v.y() > o.y_max) return false;
    return true;
  }
  // No interpenetration with a placed solid; the exact test only where the bounding boxes meet.
  bool apart(const ConvexShape& s) const {
    Eigen::AlignedBox3d box;
    for (const auto& v : s.vertices) box.extend(v);
    for (std::size_t k = 0; k < shapes.size(); ++k)
      if (box.intersects(out.scene.objects[k].bounds) && separation(s, shapes[k]) < -kTouchingTolerance_mm)
        return false;
    return true;
  }

  bool place_on_table();
  bool place_on_top();
};

bool Cluster::place_on_table() {
  for (int attempt = 0; attempt < 60; ++attempt) {
    const int ci = static_cast<int>(rng.below(catalog.size()));
    const CatalogEntry& e = catalog[static_cast<std::size_t>(ci)];
    const int face = pick(e.stable_faces);
    const Vec3 n = outward_normal(e.mesh, static_cast<std::size_t>(face), e.centroid);
    const Mat3 R = Eigen::AngleAxisd(uniform(0, kTwoPi), Vec3::UnitZ()).toRotationMatrix() *
                   Eigen::Quaterniond::FromTwoVectors(n, Vec3(0, 0, -1)).toRotationMatrix();
    const ConvexShape s = ConvexShape::of(e.mesh, R, Vec3::Zero());
    double zmin = 1e300, radius = 0;
    Vec2 lo(1e300, 1e300), hi(-1e300, -1e300);
    for (const auto& v : s.vertices) {
      zmin = std::min(zmin, v.z());
      lo = lo.cwiseMin(v.head<2>());
      hi = hi.cwiseMax(v.head<2>());
      radius = std::max(radius, v.head<2>().norm());
    }
    if (hi.x() - lo.x() > o.x_max - o.x_min || hi.y() - lo.y() > o.y_max - o.y_min) continue;
    Vec3 t(0, 0, -zmin);
    if (shapes.empty()) {
      t.x() = uniform(o.x_min - lo.x(), o.x_max - hi.x());
      t.y() = uniform(o.y_min - lo.y(), o.y_max - hi.y());
    } else {
      // Out from a table object's centre until every solid is `gap` away.
      std::vector<int> on_table;
      for (std::size_t k = 0; k < shapes.size(); ++k)
        if (out.support[k] < 0) on_table.push_back(static_cast<int>(k));
      const auto& box = out.scene.objects[static_cast<std::size_t>(pick(on_table))].bounds;
      const Vec2 c = box.center().head<2>();
      const double a = uniform(0, kTwoPi);
      const Vec2 dir(std::cos(a), std::sin(a));
      const double gap = uniform(o.clutter_gap_min_mm, o.clutter_gap_max_mm);
      std::vector<std::optional<PairSeparation>> pairs(shapes.size());  // built when first needed
      auto clear = [&](double r) {
        const Vec3 at(c.x() + r * dir.x(), c.y() + r * dir.y(), t.z());
        for (std::size_t k = 0; k < shapes.size(); ++k) {
          if (!pairs[k]) pairs[k].emplace(s, shapes[k]);
          if (!pairs[k]->at_least(at, gap)) return false;
        }
        return true;
      };
      double r_in = 0, r_out = 0.5 * (box.max() - box.min()).head<2>().norm() + radius + gap + 1.0;
      if (clear(r_in) || !clear(r_out)) continue;
      for (int it = 0; it < 40; ++it) {
        const double mid = 0.5 * (r_in + r_out);
        (clear(mid) ? r_out : r_in) = mid;
      }
      t.x() = c.x() + r_out * dir.x();
      t.y() = c.y() + r_out * dir.y();
    }
    if (t.x() + lo.x() < o.x_min || t.x() + hi.x() > o.x_max || t.y() + lo.y() < o.y_min ||
        t.y() + hi.y() > o.y_max)
      continue;
    add(ci, R, t, face, -1, -1);
    return true;
  }
  return false;
}

bool Cluster::place_on_top() {
  std::vector<int> bases;  // catalog objects on the table
  for (std::size_t k = 0; k < shapes.size(); ++k)
    if (out.support[k] < 0 && out.catalog_index[k] >= 0) bases.push_back(static_cast<int>(k));
  if (bases.empty()) return false;
  const double cos_tilt = std::cos(o.stack_max_tilt_deg * std::numbers::pi / 180.0);
  for (int attempt = 0; attempt < 80; ++attempt) {
    const auto k = static_cast<std::size_t>(pick(bases));
    const SceneObject& base = out.scene.objects[k];
    std::vector<int> up;
    for (std::size_t f = 0; f < base.faces.size(); ++f)
      if (base.faces[f].plane.n.z() >= cos_tilt) up.push_back(static_cast<int>(f));
    if (up.empty()) continue;
    const int sf = pick(up);
    const WorldFace& top = base.faces[static_cast<std::size_t>(sf)];
    const Vec3 n = top.plane.n;
    double h = -1e300;  // the supporting plane n.x = h: the base's extreme along n
    for (const auto& v : shapes[k].vertices) h = std::max(h, n.dot(v));

    // A point of the supporting face, stack_margin_mm inside: the upper centroid's vertical projection.
    const Vec3 u = n.unitOrthogonal(), w = n.cross(u);
    double u_lo = 1e300, u_hi = -1e300, w_lo = 1e300, w_hi = -1e300;
    for (const auto& x : top.polygon) {
      u_lo = std::min(u_lo, u.dot(x)), u_hi = std::max(u_hi, u.dot(x));
      w_lo = std::min(w_lo, w.dot(x)), w_hi = std::max(w_hi, w.dot(x));
    }
    Vec3 p;
    bool inside = false;
    for (int tries = 0; tries < 30 && !inside; ++tries) {
      p = h * n + uniform(u_lo, u_hi) * u + uniform(w_lo, w_hi) * w;
      inside = inside_depth(top.polygon, n, p) >= o.stack_margin_mm;
    }
    if (!inside) continue;

    const int ci = static_cast<int>(rng.below(catalog.size()));
    const CatalogEntry& e = catalog[static_cast<std::size_t>(ci)];
    const int face = pick(e.stable_faces);
    const Vec3 m = outward_normal(e.mesh, static_cast<std::size_t>(face), e.centroid);
    const Mat3 R = Eigen::AngleAxisd(uniform(0, kTwoPi), n).toRotationMatrix() *
                   Eigen::Quaterniond::FromTwoVectors(m, -n).toRotationMatrix();
    // Centroid straight above p, resting face on the plane n.x = h.
    double lowest = 1e300;
    for (const auto& v : e.mesh.vertices) lowest = std::min(lowest, n.dot(R * v));
    const Vec3 centroid = R * e.centroid;
    const Vec3 t = p + (n.dot(centroid) - lowest) / n.z() * Vec3::UnitZ() - centroid;
    std::vector<Vec3> resting;
    for (auto i : e.mesh.faces[static_cast<std::size_t>(face)]) resting.push_back(R * e.mesh.vertices[i] + t);
    if (inside_depth(resting, n, p) < o.stack_margin_mm) continue;

    const ConvexShape s = ConvexShape::of(e.mesh, R, t);
    if (std::any_of(s.vertices.begin(), s.vertices.end(),
                    [](const Vec3& v) { return v.z() < kAboveTable_mm; }))
      continue;
    if (!in_rect(s) || !apart(s)) continue;

    // The base with everything on it must not tip over either.
    auto weighted = [&](std::size_t j) {
      const CatalogEntry& c = catalog[static_cast<std::size_t>(out.catalog_index[j])];
      const double v = volume_of(c);
      const SceneObject& ob = out.scene.objects[j];
      return std::pair<double, Vec3>(v, v * (ob.rotation * c.centroid + ob.translation));
    };
    auto [volume, moment] = weighted(k);
    for (std::size_t j = 0; j < shapes.size(); ++j)
      if (out.support[j] == static_cast<int>(k)) {
        const auto [v, mo] = weighted(j);
        volume += v, moment += mo;
      }
    volume += volume_of(e);
    moment += volume_of(e) * (p + (n.dot(centroid) - lowest) / n.z() * Vec3::UnitZ());
    const Vec3 com = moment / volume;
    const auto& bottom = base.faces[static_cast<std::size_t>(out.resting_face[k])].polygon;
    if (inside_depth(bottom, Vec3::UnitZ(), Vec3(com.x(), com.y(), 0)) <= 0) continue;

    add(ci, R, t, face, static_cast<int>(k), sf);
    return true;
  }
  return false;
}

}  // namespace

bool place_cluttered(const std::vector<CatalogEntry>& catalog, const RandomSceneOptions& o, Prng& rng,
                     RandomScene& out) {
  Cluster cluster{catalog, o, rng, out, {}};
  const int want = o.clutter_min_objects + static_cast<int>(rng.below(static_cast<std::uint64_t>(
                                               o.clutter_max_objects - o.clutter_min_objects + 1)));
  std::vector<bool> on_top(static_cast<std::size_t>(want), false);
  for (int i = 0; i < o.stacked_objects && want > 1; ++i)
    on_top[1 + rng.below(static_cast<std::uint64_t>(want - 1))] = true;
  for (int i = 0; i < want; ++i) {
    bool ok = on_top[static_cast<std::size_t>(i)] && cluster.place_on_top();
    if (!ok) ok = cluster.place_on_table();
    if (!ok) break;
  }
  return static_cast<int>(out.scene.objects.size()) >= o.clutter_min_objects;
}

}  // namespace fs::sim
