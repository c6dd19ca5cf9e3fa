// The export and calibrate commands (host/io/io_tools.hpp, what `facetscan export|calibrate` run).
#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <sstream>

#include "common/error.hpp"
#include "common/scan_file.hpp"
#include "fscan_file.hpp"
#include "host/io/calibration_json.hpp"
#include "host/io/io_tools.hpp"
#include "synth_scan.hpp"

namespace fs::host {
namespace {

struct Dir {
  std::filesystem::path p =
      std::filesystem::temp_directory_path() / ("fs_io_tools_" + std::to_string(::getpid()));
  Dir() { std::filesystem::create_directories(p); }
  ~Dir() { std::filesystem::remove_all(p); }
  std::string operator()(const std::string& n) const { return (p / n).string(); }
};

void write_fscan(const std::string& path, const fs::test::SynthScan& s) {
  fs::test::write_fscan(std::filesystem::path(path), s);
}

TEST(IoTools, CalibrateFromFscanTargetsWritesCalibrationFile) {
  Dir dir;
  const auto nominal = ScannerCalibration::bench_default(60);
  const auto truth = fs::test::perturbed_truth(nominal);
  CalibrateArgs args;
  for (double h : {0.0, 30.0, 60.0}) {
    const auto path = dir("flat_" + std::to_string(int(h)) + ".fscan");
    write_fscan(path, fs::test::synth_flat_scan(truth, nominal, h, 0.05, 3 + int(h), 1, 16));
    args.targets.push_back(path + "@" + std::to_string(h));
  }
  args.output = dir("cal.json");
  args.options.row_stride = 1;
  std::ostringstream log;
  const auto r = run_calibrate(args, log);
  EXPECT_LT(r.rms_after_mm, 0.1) << log.str();
  EXPECT_GT(r.rms_before_mm, 1.0) << log.str();
  EXPECT_NE(log.str().find("rms_after_mm"), std::string::npos);
  const auto written = read_calibration_file(args.output);
  EXPECT_TRUE(same_calibration(written, r.calibration));
  // Bad target syntax / missing file.
  CalibrateArgs bad = args;
  bad.targets[1] = dir("flat_30.fscan");
  EXPECT_THROW(run_calibrate(bad, log), fs::Error);
  bad.targets[1] = dir("nope.fscan@3");
  EXPECT_THROW(run_calibrate(bad, log), fs::Error);
}

TEST(IoTools, ExportScanToPlyWithColours) {
  Dir dir;
  const auto calib = ScannerCalibration::bench_default(30);
  write_fscan(dir("s.fscan"), fs::test::synth_flat_scan(calib, calib, 5.0, 0.0, 1, 1, 32));
  ExportArgs a;
  a.input = dir("s.fscan");
  a.output = dir("s.ply");
  std::ostringstream log;
  run_export(a, log);
  EXPECT_NE(log.str().find("30 x 1024 organized"), std::string::npos) << log.str();
  OrganizedCloud back;
  load_cloud(a.output, back);
  EXPECT_EQ(back.width, 30u);
  EXPECT_GT(back.valid_count(), 30u * 20);
  a.output = dir("s.txt");
  EXPECT_THROW(run_export(a, log), fs::Error);
  EXPECT_THROW(parse_units("km"), fs::Error);
  EXPECT_THROW(parse_pcd_encoding("zip"), fs::Error);
}

}  // namespace
}  // namespace fs::host
