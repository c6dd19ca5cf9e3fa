// Triangulation accuracy against hw-sim ground truth (a separate test program, test_io_accuracy, because it
// links the simulator and the firmware's stripe extractor).
#include <gtest/gtest.h>

#include "accuracy_study.hpp"
#include "support/test_paths.hpp"

namespace fs::test {
namespace {

TEST(Accuracy, EndToEndDefaultNoiseOnDefaultScene) {
  const auto scene = sim::load_scene(source_dir() / "hw-sim/scenes/default.json");
  // Every 25th of the 500 steps keeps this test fast under ASan.
  const auto r = end_to_end_accuracy(scene, 1.0, 25, 11);
  std::printf(
      "end-to-end default noise: %zu points, rms %.4f mm (all %.4f), median %.4f, p95 %.4f, gross %zu\n",
      r.points, r.rms_mm, r.rms_all_mm, r.median_mm, r.p95_mm, r.gross);
  EXPECT_GT(r.points, 5000u);
  EXPECT_LE(r.rms_mm, 0.1);
  EXPECT_LT(double(r.gross), 0.01 * double(r.points)) << "edge outliers should be rare";
  // Without any smoothing along the stripe (the firmware's per-row centres, no host smoothing) the extraction
  // noise shows fully (about twice the error); either smoothing alone takes most of it.
  host::TriangulationOptions raw;
  raw.smooth_half_window = 0;
  fw::ExtractParams per_row;
  per_row.along_stripe = 0;
  const auto r0 = end_to_end_accuracy(scene, 1.0, 25, 11, raw, 2.0, per_row);
  const auto rh = end_to_end_accuracy(scene, 1.0, 25, 11, {}, 2.0, per_row);
  const auto rf = end_to_end_accuracy(scene, 1.0, 25, 11, raw);
  std::printf(
      "end-to-end default noise: no smoothing rms %.4f mm, host smoothing only %.4f, firmware along-stripe "
      "refinement only %.4f, both (the defaults) %.4f\n",
      r0.rms_mm, rh.rms_mm, rf.rms_mm, r.rms_mm);
  EXPECT_GT(r0.rms_mm, 1.4 * r.rms_mm);
  EXPECT_GT(r0.rms_mm, 1.4 * rh.rms_mm);
  EXPECT_GT(r0.rms_mm, 1.4 * rf.rms_mm);
  EXPECT_LE(r.rms_mm,
            1.02 * rh.rms_mm);  // the firmware's refinement does not hurt the host's smoothed result
}

TEST(Accuracy, ExactColumnsGiveExactPoints) {
  auto scene = sim::load_scene(source_dir() / "hw-sim/scenes/cube.json");
  sim::resample_sweep(scene.calibration, 60);
  const auto gt = sim::make_ground_truth_grid(scene);
  host::TriangulationOptions raw;
  raw.smooth_half_window = 0;
  const auto exact = column_noise_accuracy(gt, 0.0, 1, raw);
  EXPECT_GT(exact.points, 20000u);
  EXPECT_LT(exact.rms_all_mm, 0.002);
  const auto noisy = column_noise_accuracy(gt, 0.5, 1, raw);
  EXPECT_GT(noisy.rms_mm, 10 * exact.rms_all_mm) << "noise must show";
}

}  // namespace
}  // namespace fs::test
