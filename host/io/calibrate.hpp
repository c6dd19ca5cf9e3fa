#pragma once
// Laser-plane calibration from scans of a flat target at several known heights.
//
// The camera model (intrinsics, distortion, pose) is taken as known; the laser model is estimated: the
// galvo axis (a line: 4 DOF), the plane angle at step 0 (mirror_angle_at_step0, with normal_at_zero fixed up
// to the axis) and the angle per step (rad_per_step) -- 6 parameters. optical_gain stays as given (it only
// scales rad_per_step).
//
// Residual of one stripe point: triangulate it with the model and take its signed distance to the target
// plane, the table plane raised by the target's height (mm). Levenberg-Marquardt (numeric Jacobian) from an
// initial model found linearly: each step's stripe points at >= 2 heights lie on that step's laser plane
// (fit per step), the axis is the line common to all step planes, and the plane angles vs. step give the
// offset and slope. Rows are subsampled (row_stride) to bound the work.
#include <cstdint>
#include <string>
#include <vector>

#include "common/calibration.hpp"
#include "host/io/scan.hpp"

namespace fs::host {

struct FlatTarget {
  const Scan* scan = nullptr;
  double height_mm = 0.0;  // the target plane is the table plane raised by this height along its normal
  std::string name;        // for reports
};

struct CalibrateOptions {
  std::uint32_t row_stride = 8;  // use every n-th stripe point
  int max_iterations = 50;
  bool linear_init = true;  // start from the linear estimate instead of the nominal model
  double outlier_mm = 5.0;  // points farther than this from the target after the init are dropped
};

struct TargetResidual {
  std::string name;
  double height_mm = 0.0;
  std::size_t points = 0;
  double rms_before_mm = 0.0, rms_after_mm = 0.0, max_after_mm = 0.0;
};

struct CalibrationResult {
  ScannerCalibration calibration;  // nominal with the estimated laser model
  std::vector<TargetResidual> targets;
  double rms_before_mm = 0.0;  // nominal model
  double rms_init_mm = 0.0;    // after the linear initialization
  double rms_after_mm = 0.0;   // final
  double max_after_mm = 0.0;
  std::size_t points = 0;
  std::size_t outliers = 0;
  int iterations = 0;
};

// Throws fs::Error when the targets cannot determine the model (fewer than 2 distinct heights, too few
// points, degenerate geometry).
CalibrationResult calibrate_laser(const ScannerCalibration& nominal, const std::vector<FlatTarget>& targets,
                                  const CalibrateOptions& options = {});

}  // namespace fs::host
