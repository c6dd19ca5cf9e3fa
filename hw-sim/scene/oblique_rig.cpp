#include "hw-sim/scene/oblique_rig.hpp"

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
  c.laser.aim(Vec3(0, -110, 0), Vec3(0, 110, 0), steps);
  c.table = Plane{Vec3::UnitZ(), 0.0};
  return c;
}

RandomScene make_oblique_scene(const std::vector<CatalogEntry>& catalog, RandomSceneOptions options,
                               std::uint64_t seed) {
  options.x_min = -100, options.x_max = 100, options.y_min = -85, options.y_max = 85;
  RandomScene rs = make_random_scene(catalog, options, seed);
  rs.scene.calibration = oblique_rig(options.steps);
  return rs;
}

}  // namespace fs::sim
