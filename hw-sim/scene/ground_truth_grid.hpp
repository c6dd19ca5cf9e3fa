#pragma once
// Ground truth of a whole scan, for tests of triangulation, segmentation and recognition: for every galvo
// step k of the calibration (first_step .. first_step + step_count - 1) and every image row r, what an ideal
// scanner measures (see stripe_truth.hpp): the 3D point on laser plane(k) that is lit and seen and projects
// onto row r, its sub-pixel stripe column, object id (0 table, i + 1 scene object i, -1 none) and face id
// (polygon index in the object's mesh; 0 for the table).
//
//   fs::sim::Scene scene = fs::sim::load_scene(fs::test::source_dir() / "hw-sim/scenes/cube.json");
//   fs::sim::GroundTruthGrid gt = fs::sim::make_ground_truth_grid(scene, {.depth_noise_mm = 0.2, .seed = 3});
//   const auto& c = gt.at(step_index, row);   if (c.valid()) use(c.point, c.object, c.face);
//   fs::host::OrganizedCloud cloud;  gt.export_to(cloud);   // width = steps, height = rows, labels
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <span>
#include <vector>

#include "hw-sim/scene/prng.hpp"
#include "hw-sim/scene/scene.hpp"
#include "hw-sim/scene/stripe_truth.hpp"

namespace fs::sim {

struct GroundTruthCell {
  Vec3 point{StripeSample::kNaN, StripeSample::kNaN, StripeSample::kNaN};  // measured: true + depth noise
  Vec3 true_point{StripeSample::kNaN, StripeSample::kNaN, StripeSample::kNaN};
  Vec3 normal{StripeSample::kNaN, StripeSample::kNaN, StripeSample::kNaN};  // true outward surface normal
  double column = StripeSample::kNaN;  // true sub-pixel stripe centre u in image row r
  std::int32_t object = kNoObject;
  std::int32_t face = -1;
  bool valid() const { return object != kNoObject; }
  // One integer per (object, face), unique in a scene: object * 1000 + face, -1 = none.
  std::int32_t label() const { return object < 0 ? -1 : object * 1000 + face; }
};

struct GroundTruthOptions {
  // Gaussian noise added to the depth along the camera's viewing ray (sigma, mm); 0 = exact.
  double depth_noise_mm = 0.0;
  std::uint64_t seed = 1;
};

class GroundTruthGrid {
 public:
  std::uint32_t steps() const { return steps_; }
  std::uint32_t rows() const { return rows_; }
  std::int32_t first_step() const { return calibration_.first_step; }
  const ScannerCalibration& calibration() const { return calibration_; }

  // step_index in [0, steps()), the galvo step is first_step() + step_index.
  const GroundTruthCell& at(std::uint32_t step_index, std::uint32_t row) const {
    return cells_[static_cast<std::size_t>(step_index) * rows_ + row];
  }
  std::span<const GroundTruthCell> step(std::uint32_t step_index) const {
    return {cells_.data() + static_cast<std::size_t>(step_index) * rows_, rows_};
  }
  std::span<const GroundTruthCell> cells() const { return cells_; }  // step-major
  std::size_t valid_count() const;
  std::size_t count_object(std::int32_t object) const;
  std::size_t count_face(std::int32_t object, std::int32_t face) const;

  // Fills an organized cloud (duck-typed: fs::host::OrganizedCloud) with columns = steps and rows = image
  // rows, NaN where there is nothing, labels = GroundTruthCell::label(), viewpoint = camera centre,
  // scanner = the calibration.
  template <typename Cloud>
  void export_to(Cloud& cloud, bool with_labels = true) const {
    cloud.reset(steps_, rows_, with_labels);
    for (std::uint32_t k = 0; k < steps_; ++k)
      for (std::uint32_t r = 0; r < rows_; ++r) {
        const GroundTruthCell& c = at(k, r);
        if (!c.valid()) continue;
        const std::size_t i = static_cast<std::size_t>(r) * steps_ + k;
        cloud.points[i] = c.point.template cast<float>();
        if (with_labels) cloud.labels[i] = c.label();
      }
    cloud.viewpoint = calibration_.camera.center();
    cloud.scanner = calibration_;
  }

 private:
  friend GroundTruthGrid make_ground_truth_grid(const Scene&, const GroundTruthOptions&);
  ScannerCalibration calibration_;
  std::uint32_t steps_ = 0, rows_ = 0;
  std::vector<GroundTruthCell> cells_;
};

GroundTruthGrid make_ground_truth_grid(const Scene& scene, const GroundTruthOptions& options = {});
GroundTruthGrid make_ground_truth_grid(const std::filesystem::path& scene_file,
                                       const GroundTruthOptions& options = {});

// Loses each measured point of an organized cloud (duck-typed: fs::host::OrganizedCloud) with probability
// `share`, as a real scanner's dropouts (speckle, glints, dark spots): the point becomes NaN, its label -1.
// Deterministic per seed.
template <typename Cloud>
void drop_points(Cloud& cloud, double share, std::uint64_t seed) {
  Prng rng(seed);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    if (std::isnan(cloud.points[i].z()) || rng.uniform() >= share) continue;
    cloud.points[i].setConstant(nan);
    if (i < cloud.labels.size()) cloud.labels[i] = -1;
  }
}

}  // namespace fs::sim
