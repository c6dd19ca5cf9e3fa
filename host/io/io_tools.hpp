#pragma once
// The work behind `facetscan export` and `facetscan calibrate` (host/cli/io_commands.cpp only parses the
// command line), callable from tests.
#include <ostream>
#include <string>
#include <vector>

#include "host/io/calibrate.hpp"
#include "host/io/cloud_writers.hpp"
#include "host/io/load.hpp"

namespace fs::host {

struct ExportArgs {
  std::string input;   // .fscan | .pcd | .ply
  std::string output;  // .pcd | .ply
  LoadOptions load;
  CloudWriteOptions write;
  PcdEncoding pcd_encoding = PcdEncoding::BinaryCompressed;
};
// Loads, writes, and prints a one-line summary to `log`.
void run_export(const ExportArgs& args, std::ostream& log);

struct CalibrateArgs {
  std::vector<std::string> targets;  // "scan.fscan@HEIGHT_MM"
  std::string nominal;               // calibration JSON; empty: the first scan's ScanBegin calibration
  std::string output;                // calibration JSON to write
  CalibrateOptions options;
};
// Runs the calibration, prints the residual table to `log`, writes the calibration file (with a
// "residuals" member). Returns the result.
CalibrationResult run_calibrate(const CalibrateArgs& args, std::ostream& log);

PcdEncoding parse_pcd_encoding(const std::string& s);
Units parse_units(const std::string& s);

}  // namespace fs::host
