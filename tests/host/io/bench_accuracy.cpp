// Prints the triangulation accuracy tables (RMS 3D error vs. noise, with and without stripe smoothing) on
// hw-sim's default scene. Not a timing benchmark: run it once, `bench_accuracy` (no arguments).
#include <cstdio>

#include "accuracy_study.hpp"
#include "support/test_paths.hpp"

int main() {
  using namespace fs::test;
  const auto scene = fs::sim::load_scene(source_dir() / "hw-sim/scenes/default.json");
  fs::host::TriangulationOptions raw;
  raw.smooth_half_window = 0;
  const fs::host::TriangulationOptions smoothed{};  // defaults: +-2 rows
  const fs::host::TriangulationOptions* settings[] = {&smoothed, &raw};
  for (const fs::host::TriangulationOptions* o : settings) {
    std::printf(
        "\nEnd to end (renderer noise x scale -> firmware %s extraction -> triangulation, smoothing "
        "half window %u), every 5th of 500 steps:\n",
        fs::fw::to_string(fs::fw::ExtractParams{}.method), o->smooth_half_window);
    std::printf(
        "| noise_scale | points | rms_mm (<=2 mm) | rms_all_mm | median_mm | p95_mm | gross (>2 mm) |\n");
    std::printf("|---|---|---|---|---|---|---|\n");
    for (double s : {0.0, 0.5, 1.0, 2.0, 4.0}) {
      const auto r = end_to_end_accuracy(scene, s, 5, 11, *o);
      std::printf("| %.1f | %zu | %.4f | %.4f | %.4f | %.4f | %zu |\n", s, r.points, r.rms_mm, r.rms_all_mm,
                  r.median_mm, r.p95_mm, r.gross);
    }
  }
  const auto gt = fs::sim::make_ground_truth_grid(scene);
  std::printf("\nTrue stripe columns + Gaussian column noise, no smoothing (all 500 steps):\n");
  std::printf("| sigma_px | points | rms_mm | median_mm | p95_mm |\n|---|---|---|---|---|\n");
  for (double s : {0.0, 0.02, 0.05, 0.1, 0.2, 0.5}) {
    const auto r = column_noise_accuracy(gt, s, 3, raw);
    std::printf("| %.2f | %zu | %.4f | %.4f | %.4f |\n", s, r.points, r.rms_mm, r.median_mm, r.p95_mm);
  }
  return 0;
}
