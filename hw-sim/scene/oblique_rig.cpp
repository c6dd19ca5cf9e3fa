#include "hw-sim/scene/oblique_rig.hpp"

#include <cmath>

namespace fs::sim {

ScannerCalibration oblique_rig(std::uint32_t steps) {
  ScannerCalibration c;
  c.step_count = steps;
  c.first_step = 0;
  c.camera = CameraModel{};
  c.camera.width = 400;
  c.camera.height = 320;
  c.camera.fx = c.camera.fy = 560.0;
  c.camera.cx = 199.5;
  c.camera.cy = 159.5;
  c.camera.t_world_cam = Vec3(0, -180, 520);
  // Camera axes in world coordinates: z toward the table origin, y (image down) along world x, x = y cross z.
  const Vec3 z = (Vec3::Zero() - c.camera.t_world_cam).normalized();
  const Vec3 y = Vec3::UnitX();
  const Vec3 x = y.cross(z).normalized();
  c.camera.R_world_cam.col(0) = x;
  c.camera.R_world_cam.col(1) = y;
  c.camera.R_world_cam.col(2) = z;

  c.laser.axis_point = Vec3(0, 150, 480);
  c.laser.axis_dir = Vec3::UnitX();
  c.laser.optical_gain = 2.0;
  const Vec3 to_origin = (Vec3::Zero() - c.laser.axis_point).normalized();
  c.laser.normal_at_zero = c.laser.axis_dir.cross(to_origin).normalized();
  auto plane_angle_for_y = [&](double y_table) {
    const Vec3 dir = (Vec3(0, y_table, 0) - c.laser.axis_point).normalized();
    return std::atan2(to_origin.cross(dir).dot(c.laser.axis_dir), to_origin.dot(dir));
  };
  const double a0 = plane_angle_for_y(-110.0) / c.laser.optical_gain;
  const double a1 = plane_angle_for_y(110.0) / c.laser.optical_gain;
  c.laser.mirror_angle_at_step0 = a0;
  c.laser.rad_per_step = steps > 1 ? (a1 - a0) / static_cast<double>(steps - 1) : 0.0;
  c.table = Plane{Vec3::UnitZ(), 0.0};
  return c;
}

}  // namespace fs::sim
