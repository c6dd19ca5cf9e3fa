#include "common/calibration.hpp"

#include <cmath>

namespace fs {

Vec2 CameraModel::distort(const Vec2& xn) const {
  const double x = xn.x(), y = xn.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
  return {x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
          y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y};
}

Vec2 CameraModel::undistort_pixel(const Vec2& px) const {
  const Vec2 xd((px.x() - cx) / fx, (px.y() - cy) / fy);
  Vec2 xn = xd;
  for (int it = 0; it < 20; ++it) {
    const Vec2 err = distort(xn) - xd;
    xn -= err;
    if (err.squaredNorm() < 1e-24) break;
  }
  return xn;
}

bool CameraModel::project(const Vec3& x_world, Vec2& px) const {
  const Vec3 xc = R_world_cam.transpose() * (x_world - t_world_cam);
  if (xc.z() <= 1e-9) return false;
  const Vec2 xd = distort(Vec2(xc.x() / xc.z(), xc.y() / xc.z()));
  px = Vec2(fx * xd.x() + cx, fy * xd.y() + cy);
  return true;
}

Vec3 CameraModel::ray_world(const Vec2& px) const {
  const Vec2 xn = undistort_pixel(px);
  return (R_world_cam * Vec3(xn.x(), xn.y(), 1.0)).normalized();
}

Plane LaserModel::plane_at_mirror_angle(double mirror_angle_rad) const {
  const Eigen::AngleAxisd rot(optical_gain * mirror_angle_rad, axis_dir.normalized());
  Plane p;
  p.n = (rot * normal_at_zero).normalized();
  p.d = p.n.dot(axis_point);
  return p;
}

double LaserModel::step_through(const Vec3& x, double near_step) const {
  const Vec3 a = axis_dir.normalized();
  Vec3 v = x - axis_point;
  v -= v.dot(a) * a;
  if (v.squaredNorm() < 1e-18 || rad_per_step == 0.0 || optical_gain == 0.0) return std::nan("");
  // A direction in the plane at angle 0, across the axis; the plane through x is at the angle of v from it,
  // up to a half turn (a plane's normal has two signs): the one nearest the plane of near_step.
  const Vec3 d0 = normal_at_zero.cross(a).normalized();
  const double angle = std::atan2(d0.cross(v).dot(a), d0.dot(v));
  const double ref = optical_gain * mirror_angle(near_step);
  const double plane_angle = ref + std::remainder(angle - ref, M_PI);
  return (plane_angle / optical_gain - mirror_angle_at_step0) / rad_per_step;
}

bool ScannerCalibration::covers(const Vec3& x) const {
  Vec2 px;
  if (!camera.project(x, px)) return false;
  if (!(px.x() >= -0.5 && px.x() < camera.width - 0.5 && px.y() >= -0.5 && px.y() < camera.height - 0.5))
    return false;
  const double step = laser.step_through(x, first_step + 0.5 * (static_cast<double>(step_count) - 1.0));
  return step >= first_step - 0.5 && step <= first_step + static_cast<double>(step_count) - 0.5;
}

ScannerCalibration ScannerCalibration::bench_default(std::uint32_t step_count) {
  ScannerCalibration c;
  c.step_count = step_count;
  c.first_step = 0;
  c.camera = CameraModel{};
  c.camera.k1 = -0.04;
  c.camera.k2 = 0.01;
  // Looking straight down: camera x = world x, camera y = world -y, camera z = world -z.
  c.camera.R_world_cam << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  c.camera.t_world_cam = Vec3(0, 0, 500);

  c.laser.axis_point = Vec3(200, 0, 500);
  c.laser.axis_dir = Vec3::UnitY();
  c.laser.optical_gain = 2.0;
  // Sweep the stripe over table x in [-150, 150].
  c.laser.aim(Vec3(-150, 0, 0), Vec3(150, 0, 0), step_count);
  c.table = Plane{Vec3::UnitZ(), 0.0};
  return c;
}

void LaserModel::aim(const Vec3& first, const Vec3& last, std::uint32_t steps) {
  // Plane at mirror angle 0 passes through the origin: it contains the axis and the direction
  // (origin - axis_point); its normal is perpendicular to both.
  const Vec3 to_origin = (Vec3::Zero() - axis_point).normalized();
  normal_at_zero = axis_dir.cross(to_origin).normalized();
  // Plane angles relative to angle 0 (about axis_dir).
  auto plane_angle = [&](const Vec3& x) {
    const Vec3 dir = (x - axis_point).normalized();
    // signed angle from to_origin to dir about axis_dir
    return std::atan2(to_origin.cross(dir).dot(axis_dir), to_origin.dot(dir));
  };
  const double a0 = plane_angle(first) / optical_gain;
  const double a1 = plane_angle(last) / optical_gain;
  mirror_angle_at_step0 = a0;
  rad_per_step = steps > 1 ? (a1 - a0) / static_cast<double>(steps - 1) : 0.0;
}

bool intersect_ray_plane(const Vec3& origin, const Vec3& dir, const Plane& plane, double cos_min, Vec3& hit) {
  const double denom = plane.n.dot(dir);
  if (std::abs(denom) < cos_min) return false;
  const double s = (plane.d - plane.n.dot(origin)) / denom;
  if (s <= 0.0) return false;
  hit = origin + s * dir;
  return true;
}

}  // namespace fs
