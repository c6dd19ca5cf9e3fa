// Laser calibration on hw-sim renders: flat-target scans at several known heights are rendered with
// a perturbed ("true") scanner geometry and extracted by the firmware's extractor; the scans' headers carry
// the nominal geometry. `calibrate_laser` (and the `facetscan calibrate` binary on .fscan files of the same
// renders) must recover a laser model that triangulates another rendered scene (the cube) with an RMS 3D
// error below 0.1 mm against the renderer's ground truth, while the nominal model is millimetres off.
#include <gtest/gtest.h>

#include <unistd.h>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "host/io/calibrate.hpp"
#include "host/io/calibration_json.hpp"
#include "render_scan.hpp"
#include "support/test_paths.hpp"

namespace fs::test {
namespace {

// 40 steps over the full sweep keep the renders cheap under ASan (a render + extraction per step).
constexpr std::uint32_t kSteps = 40;
constexpr double kHeights[] = {0.0, 20.0, 40.0, 60.0};

struct Renders {
  ScannerCalibration nominal = ScannerCalibration::bench_default(kSteps);
  ScannerCalibration truth = perturbed_truth(nominal);
  std::vector<SynthScan> targets;  // one per kHeights entry, default noise
  SynthScan cube;                  // the check scene, default noise
  Renders() {
    for (std::size_t i = 0; i < std::size(kHeights); ++i)
      targets.push_back(render_scan(flat_target_scene(truth, kHeights[i]), nominal, 1.0, 10 + i));
    sim::Scene scene = sim::load_scene(source_dir() / "hw-sim/scenes/cube.json");
    scene.calibration = truth;
    cube = render_scan(scene, nominal, 1.0, 99);
  }
};

const Renders& renders() {
  static const Renders r;
  return r;
}

struct TempDir {
  std::filesystem::path p =
      std::filesystem::temp_directory_path() / ("fs_io_calr_" + std::to_string(::getpid()));
  TempDir() { std::filesystem::create_directories(p); }
  ~TempDir() { std::filesystem::remove_all(p); }
};

TEST(CalibrateRendered, FlatTargetsAreSeenWholeAndFlat) {
  const auto& r = renders();
  for (std::size_t i = 0; i < std::size(kHeights); ++i) {
    const auto& s = r.targets[i];
    std::size_t n = 0;
    double max_dz = 0;
    for (const auto& p : s.truth.points) {
      if (!host::OrganizedCloud::valid(p)) continue;
      ++n;
      max_dz = std::max(max_dz, std::abs(double(p.z()) - kHeights[i]));
    }
    EXPECT_GT(n, std::size_t(kSteps) * 900) << "height " << kHeights[i];
    EXPECT_LT(max_dz, 1e-3) << "every lit point is on the target's top face";
    std::size_t extracted = 0;
    for (const auto& st : s.stripes) extracted += st.points.size();
    EXPECT_GT(extracted, std::size_t(kSteps) * 900);
  }
}

TEST(CalibrateRendered, RecoversPerturbedGeometryAndTriangulatesTheCubeScene) {
  const auto& r = renders();
  std::vector<host::Scan> scans(std::size(kHeights));
  std::vector<host::FlatTarget> targets;
  for (std::size_t i = 0; i < scans.size(); ++i) {
    fill_scan(r.targets[i], scans[i]);
    targets.push_back({&scans[i], kHeights[i], "h" + std::to_string(int(kHeights[i]))});
  }
  const host::CalibrationResult res = host::calibrate_laser(r.nominal, targets);
  std::printf(
      "rendered flat targets (0/20/40/60 mm, default noise, %u steps): residual rms %.4f mm (nominal) -> "
      "%.4f (linear init) -> %.4f mm (%d iterations, %zu points, %zu outliers), max %.4f mm\n",
      kSteps, res.rms_before_mm, res.rms_init_mm, res.rms_after_mm, res.iterations, res.points, res.outliers,
      res.max_after_mm);
  EXPECT_GT(res.rms_before_mm, 1.0) << "the perturbation must matter";
  EXPECT_LT(res.rms_after_mm, 0.1);
  for (const auto& t : res.targets) {
    EXPECT_LT(t.rms_after_mm, 0.1) << t.name;
    EXPECT_GT(t.points, 3000u) << t.name;
  }
  EXPECT_LT(res.outliers, res.points / 100);

  const ModelError before = model_error(r.cube, r.nominal);
  const ModelError after = model_error(r.cube, res.calibration);
  const ModelError ideal = model_error(r.cube, r.truth);
  std::printf(
      "cube scene 3D error vs ground truth (%zu points): nominal model rms %.4f mm (%zu > 2 mm), "
      "calibrated %.4f mm (all %.4f, %zu > 2 mm), true model %.4f mm\n",
      after.points, before.rms_all_mm, before.gross, after.rms_mm, after.rms_all_mm, after.gross,
      ideal.rms_mm);
  EXPECT_GT(after.points, std::size_t(kSteps) * 800);
  EXPECT_GT(before.rms_all_mm, 1.0) << "the nominal model must be far off";
  EXPECT_LT(after.rms_mm, 0.1) << "RMS 3D error after calibration";
  EXPECT_LT(after.gross, after.points / 200) << "only stripes straddling depth edges may be far off";
  EXPECT_LT(after.rms_mm, ideal.rms_mm + 0.02) << "nearly as good as knowing the true geometry";
  const double model_only = model_difference(r.cube, res.calibration, r.truth);
  std::printf("model error alone (calibrated vs true model on the same stripes): %.4f mm\n", model_only);
  EXPECT_LT(model_only, 0.02);
  // The recovered planes agree with the true ones across the sweep.
  for (double step : {0.0, kSteps / 2.0, kSteps - 1.0}) {
    const Plane a = r.truth.laser.plane_at_step(step), b = res.calibration.laser.plane_at_step(step);
    EXPECT_LT(std::acos(std::min(1.0, a.n.dot(b.n))), 3e-4) << step;
  }
}

TEST(CalibrateRendered, TwoHeightsSuffice) {
  const auto& r = renders();
  host::Scan a, b;
  fill_scan(r.targets[0], a);
  fill_scan(r.targets[3], b);
  const auto res = host::calibrate_laser(r.nominal, {{&a, kHeights[0], "low"}, {&b, kHeights[3], "high"}});
  const ModelError after = model_error(r.cube, res.calibration);
  std::printf("two heights (0/60 mm): residual rms %.4f -> %.4f mm, cube 3D error %.4f mm\n",
              res.rms_before_mm, res.rms_after_mm, after.rms_mm);
  EXPECT_LT(after.rms_mm, 0.1);
}

// The command-line path: .fscan files of the renders -> the facetscan binary -> calibration JSON.
TEST(CalibrateRendered, FacetscanCalibrateOnFscanFiles) {
  const auto& r = renders();
  TempDir dir;
  std::string cmd = (bin_dir() / "facetscan").string() + " calibrate";
  for (std::size_t i = 0; i < std::size(kHeights); ++i) {
    const auto path = dir.p / ("flat" + std::to_string(int(kHeights[i])) + ".fscan");
    write_fscan(path, r.targets[i]);
    cmd += " --target " + path.string() + "@" + std::to_string(kHeights[i]);
  }
  const auto out = dir.p / "calib.json";
  const auto log_path = dir.p / "log.txt";
  cmd += " -o " + out.string() + " > " + log_path.string() + " 2>&1";
  const int status = std::system(cmd.c_str());
  std::stringstream log;
  log << std::ifstream(log_path).rdbuf();
  ASSERT_EQ(status, 0) << cmd << "\n" << log.str();
  EXPECT_NE(log.str().find("rms_after_mm"), std::string::npos) << log.str();
  EXPECT_NE(log.str().find("flat60.fscan"), std::string::npos) << log.str();
  const ScannerCalibration cal = host::read_calibration_file(out.string());
  const ModelError after = model_error(r.cube, cal);
  std::printf("facetscan calibrate on 4 rendered .fscan targets: cube 3D error %.4f mm\n%s", after.rms_mm,
              log.str().c_str());
  EXPECT_LT(after.rms_mm, 0.1);
  // The file's residual report matches the run.
  std::ifstream f(out);
  const auto j = nlohmann::json::parse(f);
  EXPECT_LT(j.at("residuals").at("rms_after_mm").get<double>(), 0.1);
  EXPECT_GT(j.at("residuals").at("rms_before_mm").get<double>(), 1.0);
  EXPECT_EQ(j.at("residuals").at("targets").size(), std::size(kHeights));
  // Two targets at the same height cannot determine the model: a clear error, non-zero exit.
  const std::string bad = (bin_dir() / "facetscan").string() + " calibrate --target " +
                          (dir.p / "flat0.fscan").string() + "@5 --target " +
                          (dir.p / "flat20.fscan").string() + "@5 > " + log_path.string() + " 2>&1";
  EXPECT_NE(std::system(bad.c_str()), 0);
  std::stringstream bad_log;
  bad_log << std::ifstream(log_path).rdbuf();
  EXPECT_NE(bad_log.str().find("same height"), std::string::npos) << bad_log.str();
}

}  // namespace
}  // namespace fs::test
