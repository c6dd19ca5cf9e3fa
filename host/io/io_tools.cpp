#include "host/io/io_tools.hpp"

#include <cmath>

#include <fmt/format.h>

#include "common/error.hpp"
#include "common/formats/tokenizer.hpp"
#include "host/io/calibration_json.hpp"
#include "host/io/scan_assembler.hpp"

namespace fs::host {

PcdEncoding parse_pcd_encoding(const std::string& s) {
  if (s == "ascii") return PcdEncoding::Ascii;
  if (s == "binary") return PcdEncoding::Binary;
  if (s == "binary_compressed") return PcdEncoding::BinaryCompressed;
  throw Error("--pcd-encoding: '" + s + "' is not ascii, binary or binary_compressed");
}

Units parse_units(const std::string& s) {
  if (s == "auto") return Units::Auto;
  if (s == "mm") return Units::Millimetres;
  if (s == "m") return Units::Metres;
  throw Error("--units: '" + s + "' is not auto, mm or m");
}

void run_export(const ExportArgs& args, std::ostream& log) {
  OrganizedCloud cloud;
  const LoadInfo info = load_cloud(args.input, cloud, args.load);
  write_cloud(args.output, cloud, args.write, args.pcd_encoding);
  log << fmt::format("{}: {} x {} {}, {} valid points, scale {} mm/unit ({}){} -> {}\n", args.input,
                     cloud.width, cloud.height, cloud.organized ? "organized" : "unorganized",
                     info.valid_points, info.scale, info.format,
                     info.format == "fscan" ? ", scan " + info.scan_status : std::string(), args.output);
}

CalibrationResult run_calibrate(const CalibrateArgs& args, std::ostream& log) {
  if (args.targets.size() < 2)
    throw Error("calibrate: give at least two --target SCAN@HEIGHT (different heights)");
  std::vector<Scan> scans(args.targets.size());
  std::vector<FlatTarget> targets;
  for (std::size_t i = 0; i < args.targets.size(); ++i) {
    const std::string& t = args.targets[i];
    const auto at = t.rfind('@');
    double h = 0;
    if (at == std::string::npos || !formats::parse_double(std::string_view(t).substr(at + 1), h) ||
        !std::isfinite(h))
      throw Error("calibrate: target '" + t + "' must be SCAN.fscan@HEIGHT_MM");
    const std::string path = t.substr(0, at);
    load_scan(path, scans[i]);
    targets.push_back({&scans[i], h, path});
  }
  const ScannerCalibration nominal =
      args.nominal.empty() ? scans[0].begin_message().calibration : read_calibration_file(args.nominal);
  const CalibrationResult r = calibrate_laser(nominal, targets, args.options);
  log << fmt::format("{:<40} {:>10} {:>9} {:>14} {:>13} {:>12}\n", "target", "height_mm", "points",
                     "rms_before_mm", "rms_after_mm", "max_after_mm");
  nlohmann::json per_target = nlohmann::json::array();
  for (const auto& t : r.targets) {
    log << fmt::format("{:<40} {:>10.3f} {:>9} {:>14.4f} {:>13.4f} {:>12.4f}\n", t.name, t.height_mm,
                       t.points, t.rms_before_mm, t.rms_after_mm, t.max_after_mm);
    per_target.push_back({{"scan", t.name},
                          {"height_mm", t.height_mm},
                          {"points", t.points},
                          {"rms_before_mm", t.rms_before_mm},
                          {"rms_after_mm", t.rms_after_mm},
                          {"max_after_mm", t.max_after_mm}});
  }
  log << fmt::format(
      "all: {} points ({} outliers dropped), RMS {:.4f} mm (nominal) -> {:.4f} mm (linear init) -> "
      "{:.4f} mm after {} iterations, max {:.4f} mm\n",
      r.points, r.outliers, r.rms_before_mm, r.rms_init_mm, r.rms_after_mm, r.iterations, r.max_after_mm);
  if (!args.output.empty()) {
    write_calibration_file(args.output, r.calibration,
                           {{"residuals",
                             {{"rms_before_mm", r.rms_before_mm},
                              {"rms_after_mm", r.rms_after_mm},
                              {"max_after_mm", r.max_after_mm},
                              {"points", r.points},
                              {"iterations", r.iterations},
                              {"targets", per_target}}}});
    log << "wrote " << args.output << "\n";
  }
  return r;
}

}  // namespace fs::host
