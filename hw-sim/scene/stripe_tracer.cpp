#include "hw-sim/scene/stripe_tracer.hpp"

#include <algorithm>
#include <cmath>

namespace fs::sim {
namespace {

constexpr double kFarTable = 5000.0;  // mm: extent of the table line when the camera sees the horizon

}  // namespace

StripeTracer::StripeTracer(const Scene& scene) : scene_(&scene), caster_(scene) {
  std::size_t faces = 1, max_poly = 3;
  for (const SceneObject& o : scene.objects) {
    faces += o.faces.size();
    for (const WorldFace& f : o.faces) max_poly = std::max(max_poly, f.polygon.size());
  }
  segments_.reserve(faces * (max_poly / 2 + 1));
  crossings_.reserve(max_poly + 2);
  // The part of the table the camera can see: rays through the image border.
  const CameraModel& cam = scene.calibration.camera;
  const Plane& table = scene.calibration.table;
  const int n = 32;
  const double w = cam.width - 1.0, h = cam.height - 1.0;
  for (int i = 0; i <= n; ++i) {
    const double f = static_cast<double>(i) / n;
    for (const Vec2& px : {Vec2(f * w, 0), Vec2(f * w, h), Vec2(0, f * h), Vec2(w, f * h)}) {
      Vec3 hit;
      const Vec3 dir = cam.ray_world(px);
      if (intersect_ray_plane(cam.center(), dir, table, 1e-9, hit) &&
          (hit - cam.center()).norm() < kFarTable) {
        table_footprint_.push_back(hit);
      } else {
        // Horizon in view: use a far point along the ray's projection onto the table.
        const Vec3 along = (dir - table.n * table.n.dot(dir));
        const Vec3 foot = cam.center() - table.n * table.signed_distance(cam.center());
        table_footprint_.push_back(foot +
                                   (along.norm() > 1e-9 ? along.normalized() : Vec3::UnitX()) * kFarTable);
      }
    }
  }
}

void StripeTracer::add_face_segments(const Plane& laser, std::size_t oi) {
  const SceneObject& o = scene_->objects[oi];
  // Whole object on one side of the laser plane: nothing to cut.
  double lo = 1e300, hi = -1e300;
  for (int c = 0; c < 8; ++c) {
    const double d = laser.signed_distance(o.bounds.corner(static_cast<Eigen::AlignedBox3d::CornerType>(c)));
    lo = std::min(lo, d);
    hi = std::max(hi, d);
  }
  if (lo > 0 || hi < 0) return;
  const Vec3 S = laser_origin();
  const Vec3 C = scene_->calibration.camera.center();
  for (std::size_t fi = 0; fi < o.faces.size(); ++fi) {
    const WorldFace& f = o.faces[fi];
    // n . (P - x) is the same for every x on the face: facing the mirror and the camera is per face.
    if (f.plane.signed_distance(S) <= 1e-9 || f.plane.signed_distance(C) <= 1e-9) continue;
    const Vec3 dir = laser.n.cross(f.plane.n);
    if (dir.squaredNorm() < 1e-18) continue;  // face parallel to the laser plane
    crossings_.clear();
    const std::size_t m = f.polygon.size();
    Vec3 origin = Vec3::Zero();
    bool have_origin = false;
    for (std::size_t k = 0; k < m; ++k) {
      const Vec3& a = f.polygon[k];
      const Vec3& b = f.polygon[(k + 1) % m];
      const double da = laser.signed_distance(a), db = laser.signed_distance(b);
      if ((da >= 0) == (db >= 0)) continue;
      const Vec3 x = a + (b - a) * (da / (da - db));
      if (!have_origin) {
        origin = x;
        have_origin = true;
      }
      crossings_.push_back(dir.dot(x - origin));
    }
    if (crossings_.size() < 2) continue;
    std::sort(crossings_.begin(), crossings_.end());
    const Vec3 unit = dir / dir.squaredNorm();  // origin + t * unit has dir . (x - origin) = t
    for (std::size_t k = 0; k + 1 < crossings_.size(); k += 2)
      segments_.push_back({origin + crossings_[k] * unit, origin + crossings_[k + 1] * unit, f.plane.n,
                           static_cast<std::int32_t>(oi + 1), static_cast<std::int32_t>(fi)});
  }
}

void StripeTracer::add_table_segment(const Plane& laser) {
  const Plane& table = scene_->calibration.table;
  if (table.signed_distance(laser_origin()) <= 0 ||
      table.signed_distance(scene_->calibration.camera.center()) <= 0)
    return;
  const Vec3 dir = laser.n.cross(table.n);
  if (dir.squaredNorm() < 1e-18) return;
  const Vec3 u = dir.normalized();
  // A point on both planes: the one closest to the origin, p = a n1 + b n2.
  const double c = laser.n.dot(table.n);
  const double det = 1.0 - c * c;
  const double a = (laser.d - c * table.d) / det;
  const double b = (table.d - c * laser.d) / det;
  const Vec3 p = a * laser.n + b * table.n;
  double tmin = 1e300, tmax = -1e300;
  for (const Vec3& f : table_footprint_) {
    const double t = u.dot(f - p);
    tmin = std::min(tmin, t);
    tmax = std::max(tmax, t);
  }
  if (tmin > tmax) return;
  tmin -= 10.0;
  tmax += 10.0;
  segments_.push_back({p + tmin * u, p + tmax * u, table.n, kTableObject, 0});
}

void StripeTracer::consider(const Segment& s, const Vec3& x, double u, std::uint32_t row,
                            std::span<StripeSample> rows) {
  const CameraModel& cam = scene_->calibration.camera;
  if (!(u >= -0.5 && u <= cam.width - 0.5)) return;
  const Vec3 S = laser_origin();
  const Vec3 C = cam.center();
  if (caster_.blocked(S, x) || caster_.blocked(x, C)) return;
  StripeSample& out = rows[row];
  const double dc = (C - x).norm();
  ++out.candidates;
  if (out.valid() && out.camera_distance <= dc) return;
  const double dl = (S - x).norm();
  out.column = u;
  out.point = x;
  out.normal = s.normal;
  out.object = s.object;
  out.face = s.face;
  out.laser_distance = dl;
  out.camera_distance = dc;
  out.cos_incidence = s.normal.dot(S - x) / dl;
  out.cos_view = s.normal.dot(C - x) / dc;
}

void StripeTracer::solve_segment(const Segment& s, std::span<StripeSample> rows) {
  const CameraModel& cam = scene_->calibration.camera;
  const double H = static_cast<double>(rows.size());
  Vec2 pa, pb;
  const bool oka = cam.project(s.a, pa), okb = cam.project(s.b, pb);
  // Pieces short enough for the row to be monotonic along each (distortion bends the projected line).
  int pieces = 64;
  if (oka && okb) pieces = std::clamp(static_cast<int>((pb - pa).norm() / 16.0) + 1, 1, 4096);
  Vec2 prev_px = Vec2::Zero();
  bool prev_ok = false;
  double prev_t = 0.0;
  for (int i = 0; i <= pieces; ++i) {
    const double t = static_cast<double>(i) / pieces;
    const Vec3 x = s.a + t * (s.b - s.a);
    Vec2 px;
    const bool ok = cam.project(x, px);
    if (ok && prev_ok && px.y() != prev_px.y()) {
      const double v0 = prev_px.y(), v1 = px.y();
      const double lo = std::min(v0, v1), hi = std::max(v0, v1);
      // Rows r with lo <= r < hi (half-open: a row through a shared sample is solved once).
      const double r_first = std::max(0.0, std::ceil(lo));
      const double r_end = std::min(H, std::ceil(hi));
      for (double r = r_first; r < r_end; r += 1.0) {
        // Bracketed secant (Illinois) on f(t) = v(t) - r over [prev_t, t].
        double ta = prev_t, tb = t, fa = v0 - r, fb = v1 - r;
        double tm = ta;
        Vec3 xm = s.a + ta * (s.b - s.a);
        if (fa == 0.0) {
          tm = ta;
        } else {
          int side = 0;
          for (int it = 0; it < 60; ++it) {
            tm = (ta * fb - tb * fa) / (fb - fa);
            xm = s.a + tm * (s.b - s.a);
            Vec2 pm;
            if (!cam.project(xm, pm)) break;
            const double fm = pm.y() - r;
            if (std::abs(fm) < 1e-9 || std::abs(tb - ta) < 1e-15) break;
            if ((fm > 0) == (fb > 0)) {
              tb = tm;
              fb = fm;
              if (side == -1) fa *= 0.5;
              side = -1;
            } else {
              ta = tm;
              fa = fm;
              if (side == 1) fb *= 0.5;
              side = 1;
            }
          }
        }
        xm = s.a + tm * (s.b - s.a);
        Vec2 pm;
        if (!cam.project(xm, pm)) continue;
        consider(s, xm, pm.x(), static_cast<std::uint32_t>(r), rows);
      }
    }
    prev_ok = ok;
    prev_px = px;
    prev_t = t;
  }
}

void StripeTracer::trace(const Plane& laser_plane, std::span<StripeSample> rows) {
  for (StripeSample& r : rows) r = StripeSample{};
  segments_.clear();
  if (scene_->has_table) add_table_segment(laser_plane);
  for (std::size_t oi = 0; oi < scene_->objects.size(); ++oi) add_face_segments(laser_plane, oi);
  for (const Segment& s : segments_) solve_segment(s, rows);
}

}  // namespace fs::sim
