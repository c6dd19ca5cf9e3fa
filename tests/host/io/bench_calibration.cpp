// Laser calibration on hw-sim renders: how the result depends on the number of flat-target heights and on the
// renderer's noise. Flat targets and the cube check scene are rendered with the perturbed ("true") geometry
// (tests/host/io/synth_scan.hpp perturbed_truth), the calibration starts from the nominal one. Prints a
// markdown table. Not a timing benchmark: run it once, `bench_calibration [steps]` (default 100 steps over
// the sweep).
#include <cstdio>
#include <cstdlib>
#include <map>

#include "host/io/calibrate.hpp"
#include "render_scan.hpp"
#include "support/test_paths.hpp"

int main(int argc, char** argv) {
  using namespace fs::test;
  const std::uint32_t steps = argc > 1 ? static_cast<std::uint32_t>(std::atoi(argv[1])) : 100u;
  const auto nominal = fs::ScannerCalibration::bench_default(steps);
  const auto truth = perturbed_truth(nominal);
  const double heights[] = {0.0, 12.0, 24.0, 36.0, 48.0, 60.0};
  const std::vector<std::vector<int>> sets = {{0, 1}, {0, 5}, {0, 2, 5}, {0, 1, 3, 5}, {0, 1, 2, 3, 4, 5}};
  std::printf(
      "Calibration on rendered flat targets, %u steps, row stride 8; cube scene rendered at the same "
      "noise.\n",
      steps);
  std::printf(
      "| noise_scale | heights (mm) | residual rms before -> after (mm) | cube 3D rms: nominal | calibrated "
      "| "
      "true model | model alone (calibrated vs true, same stripes) |\n|---|---|---|---|---|---|---|\n");
  for (double noise : {0.5, 1.0, 2.0, 4.0}) {
    std::vector<SynthScan> targets;
    for (std::size_t i = 0; i < std::size(heights); ++i)
      targets.push_back(render_scan(flat_target_scene(truth, heights[i]), nominal, noise, 10 + i));
    fs::sim::Scene scene = fs::sim::load_scene(source_dir() / "hw-sim/scenes/cube.json");
    scene.calibration = truth;
    const SynthScan cube = render_scan(scene, nominal, noise, 99);
    const ModelError before = model_error(cube, nominal);
    const ModelError ideal = model_error(cube, truth);
    for (const auto& set : sets) {
      std::vector<fs::host::Scan> scans(set.size());
      std::vector<fs::host::FlatTarget> ft;
      std::string hs;
      for (std::size_t i = 0; i < set.size(); ++i) {
        fill_scan(targets[std::size_t(set[i])], scans[i]);
        ft.push_back({&scans[i], heights[set[i]], "h"});
        hs += (i ? "/" : "") + std::to_string(int(heights[set[i]]));
      }
      const auto res = fs::host::calibrate_laser(nominal, ft);
      const ModelError after = model_error(cube, res.calibration);
      std::printf("| %.1f | %s | %.3f -> %.4f | %.3f | **%.4f** | %.4f | %.4f |\n", noise, hs.c_str(),
                  res.rms_before_mm, res.rms_after_mm, before.rms_all_mm, after.rms_mm, ideal.rms_mm,
                  model_difference(cube, res.calibration, truth));
      std::fflush(stdout);
    }
  }
  return 0;
}
