#include "hw-sim/scene/ground_truth_grid.hpp"

#include <algorithm>

#include "hw-sim/scene/prng.hpp"
#include "hw-sim/scene/stripe_tracer.hpp"

namespace fs::sim {

std::size_t GroundTruthGrid::valid_count() const {
  return static_cast<std::size_t>(
      std::count_if(cells_.begin(), cells_.end(), [](const auto& c) { return c.valid(); }));
}

std::size_t GroundTruthGrid::count_object(std::int32_t object) const {
  return static_cast<std::size_t>(
      std::count_if(cells_.begin(), cells_.end(), [&](const auto& c) { return c.object == object; }));
}

std::size_t GroundTruthGrid::count_face(std::int32_t object, std::int32_t face) const {
  return static_cast<std::size_t>(std::count_if(
      cells_.begin(), cells_.end(), [&](const auto& c) { return c.object == object && c.face == face; }));
}

GroundTruthGrid make_ground_truth_grid(const Scene& scene, const GroundTruthOptions& options) {
  GroundTruthGrid g;
  g.calibration_ = scene.calibration;
  g.steps_ = scene.calibration.step_count;
  g.rows_ = scene.calibration.camera.height;
  g.cells_.resize(static_cast<std::size_t>(g.steps_) * g.rows_);
  StripeTracer tracer(scene);
  std::vector<StripeSample> rows(g.rows_);
  Prng rng(options.seed);
  const Vec3 C = scene.calibration.camera.center();
  for (std::uint32_t k = 0; k < g.steps_; ++k) {
    tracer.trace(scene.calibration.laser.plane_at_step(static_cast<double>(scene.calibration.first_step) + k),
                 rows);
    for (std::uint32_t r = 0; r < g.rows_; ++r) {
      const StripeSample& s = rows[r];
      if (!s.valid()) continue;
      GroundTruthCell& c = g.cells_[static_cast<std::size_t>(k) * g.rows_ + r];
      c.true_point = s.point;
      c.point = s.point;
      if (options.depth_noise_mm > 0)
        c.point += (s.point - C).normalized() * (options.depth_noise_mm * rng.gaussian());
      c.normal = s.normal;
      c.column = s.column;
      c.object = s.object;
      c.face = s.face;
    }
  }
  return g;
}

GroundTruthGrid make_ground_truth_grid(const std::filesystem::path& scene_file,
                                       const GroundTruthOptions& options) {
  return make_ground_truth_grid(load_scene(scene_file), options);
}

}  // namespace fs::sim
