#include "hw-sim/scene/ray_cast.hpp"

#include <cmath>
#include <limits>

namespace fs::sim {

SceneRayCaster::SceneRayCaster(const Scene& scene) : scene_(&scene) {
  for (const SceneObject& o : scene.objects) {
    Object obj;
    obj.bounds = o.bounds;
    obj.first_face = static_cast<std::uint32_t>(faces_.size());
    obj.face_count = static_cast<std::uint32_t>(o.faces.size());
    for (const WorldFace& wf : o.faces) {
      Face f;
      f.plane = wf.plane;
      const Vec3 an = wf.plane.n.cwiseAbs();
      f.drop_axis = an.x() >= an.y() && an.x() >= an.z() ? 0 : (an.y() >= an.z() ? 1 : 2);
      const int a0 = f.drop_axis == 0 ? 1 : 0;
      const int a1 = f.drop_axis == 2 ? 1 : 2;
      f.first = static_cast<std::uint32_t>(poly2_.size());
      f.count = static_cast<std::uint32_t>(wf.polygon.size());
      for (const Vec3& p : wf.polygon) poly2_.emplace_back(p[a0], p[a1]);
      faces_.push_back(f);
    }
    objects_.push_back(obj);
  }
}

bool SceneRayCaster::inside(const Face& f, const Vec3& x) const {
  const int a0 = f.drop_axis == 0 ? 1 : 0;
  const int a1 = f.drop_axis == 2 ? 1 : 2;
  const double px = x[a0], py = x[a1];
  bool in = false;
  const Vec2* poly = poly2_.data() + f.first;
  for (std::uint32_t i = 0, j = f.count - 1; i < f.count; j = i++) {
    const Vec2& a = poly[i];
    const Vec2& b = poly[j];
    if ((a.y() > py) != (b.y() > py)) {
      const double xc = a.x() + (py - a.y()) * (b.x() - a.x()) / (b.y() - a.y());
      if (px < xc) in = !in;
    }
  }
  return in;
}

bool SceneRayCaster::inside_face(std::size_t object_index, std::size_t face, const Vec3& x) const {
  return inside(faces_[objects_.at(object_index).first_face + face], x);
}

bool SceneRayCaster::hit_object(const Object& o, std::size_t oi, const Vec3& origin, const Vec3& dir,
                                double s_max, RayHit& hit) const {
  // Slab test against the bounding box (slightly padded).
  double t0 = 0.0, t1 = s_max;
  for (int k = 0; k < 3; ++k) {
    const double lo = o.bounds.min()[k] - 1e-6, hi = o.bounds.max()[k] + 1e-6;
    if (std::abs(dir[k]) < 1e-15) {
      if (origin[k] < lo || origin[k] > hi) return false;
      continue;
    }
    const double inv = 1.0 / dir[k];
    double a = (lo - origin[k]) * inv, b = (hi - origin[k]) * inv;
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
    if (t0 > t1) return false;
  }
  bool found = false;
  for (std::uint32_t fi = 0; fi < o.face_count; ++fi) {
    const Face& f = faces_[o.first_face + fi];
    const double denom = f.plane.n.dot(dir);
    if (std::abs(denom) < 1e-12) continue;
    const double s = (f.plane.d - f.plane.n.dot(origin)) / denom;
    if (s <= 1e-9 || s >= s_max || (found && s >= hit.s)) continue;
    const Vec3 x = origin + s * dir;
    if (!inside(f, x)) continue;
    found = true;
    hit.s = s;
    hit.point = x;
    hit.normal = f.plane.n;
    hit.object = static_cast<std::int32_t>(oi + 1);
    hit.face = static_cast<std::int32_t>(fi);
    s_max = s;
  }
  return found;
}

bool SceneRayCaster::cast(const Vec3& origin, const Vec3& dir, double s_max, RayHit& hit) const {
  bool found = false;
  if (scene_->has_table) {
    const Plane& t = scene_->calibration.table;
    const double denom = t.n.dot(dir);
    if (std::abs(denom) > 1e-12) {
      const double s = (t.d - t.n.dot(origin)) / denom;
      if (s > 1e-9 && s < s_max) {
        found = true;
        hit.s = s;
        hit.point = origin + s * dir;
        hit.normal = t.n;
        hit.object = 0;
        hit.face = 0;
        s_max = s;
      }
    }
  }
  for (std::size_t oi = 0; oi < objects_.size(); ++oi)
    if (hit_object(objects_[oi], oi, origin, dir, s_max, hit)) {
      found = true;
      s_max = hit.s;
    }
  return found;
}

bool SceneRayCaster::blocked(const Vec3& a, const Vec3& b, double eps) const {
  const Vec3 d = b - a;
  const double len = d.norm();
  if (len <= 2 * eps) return false;
  const Vec3 dir = d / len;
  RayHit h;
  return cast(a + eps * dir, dir, len - 2 * eps, h);
}

}  // namespace fs::sim
