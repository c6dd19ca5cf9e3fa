// Laser calibration from flat targets at known heights, and the calibration JSON file.
#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "common/error.hpp"
#include "host/io/calibrate.hpp"
#include "host/io/calibration_json.hpp"
#include "host/io/triangulate.hpp"
#include "synth_scan.hpp"

namespace fs::host {
namespace {

// RMS 3D distance between the cloud triangulated with `model` and the synthetic truth.
double rms_3d_error(const ScannerCalibration& model, const fs::test::SynthScan& synth,
                    std::size_t* n_out = nullptr) {
  Scan scan;
  fs::test::fill_scan(synth, scan);
  auto header = synth.begin;
  header.calibration = model;
  Scan with_model;
  with_model.start(header);
  for (std::uint32_t k = 0; k < scan.slot_count(); ++k) {
    if (!scan.has_stripe(k)) continue;
    msg::Stripe m;
    m.header = scan.stripe_header(k);
    m.points = std::span<msg::StripePoint>(const_cast<msg::StripePoint*>(scan.stripe_points(k).data()),
                                           scan.stripe_points(k).size());
    with_model.add_stripe(m);
  }
  Triangulator tri(model);
  OrganizedCloud cloud;
  tri.triangulate(with_model, cloud);
  double sq = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    if (!OrganizedCloud::valid(cloud.points[i]) || !OrganizedCloud::valid(synth.truth.points[i])) continue;
    sq += (cloud.points[i] - synth.truth.points[i]).squaredNorm();
    ++n;
  }
  if (n_out) *n_out = n;
  return n ? std::sqrt(sq / double(n)) : 1e9;
}

TEST(Calibrate, RecoversPerturbedLaserFromFlatTargets) {
  const ScannerCalibration nominal = ScannerCalibration::bench_default(120);
  const ScannerCalibration truth = fs::test::perturbed_truth(nominal);
  const double noise_px = 0.05;
  std::vector<fs::test::SynthScan> synth;
  std::vector<Scan> scans(4);
  std::vector<FlatTarget> targets;
  const double heights[] = {0.0, 25.0, 50.0, 75.0};
  for (int i = 0; i < 4; ++i)
    synth.push_back(fs::test::synth_flat_scan(truth, nominal, heights[i], noise_px, 10 + i, 1, 8));
  for (int i = 0; i < 4; ++i) {
    fs::test::fill_scan(synth[static_cast<std::size_t>(i)], scans[static_cast<std::size_t>(i)]);
    targets.push_back(
        {&scans[static_cast<std::size_t>(i)], heights[i], "h" + std::to_string(int(heights[i]))});
  }
  CalibrateOptions opt;
  opt.row_stride = 1;  // the synthetic scans already use every 8th row
  const CalibrationResult res = calibrate_laser(nominal, targets, opt);
  EXPECT_GT(res.rms_before_mm, 1.0) << "the perturbation must matter";
  EXPECT_LT(res.rms_after_mm, 0.1);
  EXPECT_EQ(res.targets.size(), 4u);
  for (const auto& t : res.targets) {
    EXPECT_LT(t.rms_after_mm, 0.1) << t.name;
    EXPECT_GT(t.points, 1000u) << t.name;
  }
  // 3D accuracy on an independent scan (another height, new noise) against the true points.
  const auto check = fs::test::synth_flat_scan(truth, nominal, 37.0, noise_px, 99, 1, 8);
  std::size_t n = 0;
  const double before = rms_3d_error(nominal, check, &n);
  const double after = rms_3d_error(res.calibration, check);
  EXPECT_GT(n, 5000u);
  EXPECT_GT(before, 1.0);
  EXPECT_LT(after, 0.1) << "RMS 3D error after calibration";
  std::printf(
      "calibration: residual rms %.4f mm (nominal) -> %.4f (linear init) -> %.4f mm (%d iterations); "
      "3D error on an independent scan %.4f -> %.4f mm\n",
      res.rms_before_mm, res.rms_init_mm, res.rms_after_mm, res.iterations, before, after);
  // The recovered planes agree with the true ones across the sweep.
  for (double step : {0.0, 60.0, 119.0}) {
    const Plane a = truth.laser.plane_at_step(step), b = res.calibration.laser.plane_at_step(step);
    EXPECT_LT(std::acos(std::min(1.0, a.n.dot(b.n))), 2e-4) << step;
  }
}

TEST(Calibrate, WithoutLinearInitStillConvergesFromNominal) {
  const ScannerCalibration nominal = ScannerCalibration::bench_default(60);
  const ScannerCalibration truth = fs::test::perturbed_truth(nominal);
  std::vector<Scan> scans(2);
  std::vector<FlatTarget> targets;
  const double heights[] = {0.0, 60.0};
  for (int i = 0; i < 2; ++i) {
    fs::test::fill_scan(fs::test::synth_flat_scan(truth, nominal, heights[i], 0.0, 1, 1, 16),
                        scans[std::size_t(i)]);
    targets.push_back({&scans[std::size_t(i)], heights[i], "t"});
  }
  CalibrateOptions opt;
  opt.linear_init = false;
  opt.row_stride = 1;
  opt.outlier_mm = 100.0;
  const auto res = calibrate_laser(nominal, targets, opt);
  EXPECT_LT(res.rms_after_mm, 1e-3);
}

TEST(Calibrate, RefusesUnderdeterminedInput) {
  const ScannerCalibration nominal = ScannerCalibration::bench_default(30);
  Scan a, b;
  fs::test::fill_scan(fs::test::synth_flat_scan(nominal, nominal, 10.0, 0.0, 1, 1, 32), a);
  fs::test::fill_scan(fs::test::synth_flat_scan(nominal, nominal, 10.0, 0.0, 2, 1, 32), b);
  EXPECT_THROW(calibrate_laser(nominal, {{&a, 10.0, "a"}}), fs::Error);
  EXPECT_THROW(calibrate_laser(nominal, {{&a, 10.0, "a"}, {&b, 10.0, "b"}}), fs::Error);
  Scan empty;
  EXPECT_THROW(calibrate_laser(nominal, {{&a, 10.0, "a"}, {&empty, 20.0, "b"}}), fs::Error);
}

TEST(CalibrationJson, RoundTripsAndRejectsBadFields) {
  const ScannerCalibration c = fs::test::perturbed_truth(ScannerCalibration::bench_default(321));
  const auto j = calibration_to_json(c);
  const ScannerCalibration back = calibration_from_json(j, "mem");
  EXPECT_TRUE(same_calibration(c, back));
  EXPECT_EQ(back.table.n, c.table.n);
  auto expect_bad = [&](nlohmann::json bad, const std::string& fragment) {
    try {
      calibration_from_json(bad, "cal.json");
      ADD_FAILURE() << "accepted: " << fragment;
    } catch (const fs::Error& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("cal.json"), std::string::npos) << e.what();
    }
  };
  auto bad = j;
  bad["camera"].erase("fx");
  expect_bad(bad, "camera.fx: missing");
  bad = j;
  bad["laser"]["rad_per_step"] = "fast";
  expect_bad(bad, "laser.rad_per_step: is not a number");
  bad = j;
  bad["camera"]["R_world_cam"][0][0] = 2.0;
  expect_bad(bad, "not a rotation");
  bad = j;
  bad["laser"]["axis_point"] = {1, 2};
  expect_bad(bad, "laser.axis_point");
  bad = j;
  bad["step_count"] = -5;
  expect_bad(bad, "step_count");
  bad = j;
  bad["laser"]["normal_at_zero"] =
      c.laser.axis_dir.x() == 0 ? nlohmann::json{0, 1, 0} : nlohmann::json{1, 0, 0};
  bad["laser"]["axis_dir"] = bad["laser"]["normal_at_zero"];
  expect_bad(bad, "perpendicular");
  expect_bad(nlohmann::json::array(), "not a JSON object");
  // Files: write/read, and a syntax error names the byte.
  const auto dir = std::filesystem::temp_directory_path() / ("fs_io_cal_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto path = (dir / "cal.json").string();
  write_calibration_file(path, c, {{"residuals", {{"rms_mm", 0.01}}}});
  EXPECT_TRUE(same_calibration(read_calibration_file(path), c));
  std::ofstream(path) << "{\"camera\": [1, 2,";
  try {
    read_calibration_file(path);
    ADD_FAILURE();
  } catch (const fs::Error& e) {
    EXPECT_NE(std::string(e.what()).find("at byte"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace fs::host
