#pragma once
// Laser-stripe triangulation: the camera ray through each undistorted sub-pixel stripe point, intersected
// with the laser plane of its galvo step, gives a 3D point (mm, world frame) at (row = image row,
// column = step - first_step) of an OrganizedCloud.
//
// Speed: configure() precomputes, for every image row and integer column, the world-frame direction of the
// undistorted ray R_world_cam * (x_n, y_n, 1) (linear in the pixel apart from distortion, so linear
// interpolation between neighbouring columns is accurate to ~1e-9 rad), and per galvo step the plane normal
// n_k and e_k = d_k - n_k . C. A point then costs an interpolation, two dot products and a division.
// Memory: rows x (cols + 1) x 12 bytes (16 MB for 1280 x 1024), allocated by configure() after checking the
// camera and the grid against TriangulationOptions::limits (the memory budget: a camera whose ray table or a
// scan whose grid does not fit is refused with fs::Error before anything is allocated); triangulating a scan
// into a cloud whose capacity suffices allocates nothing. release() frees the tables (after a scan with an
// unusually large camera).
//
// One cell per (row, step): when several points of a stripe fall in the same image row, the cell keeps the
// brightest (highest peak; on a tie the first) of those that triangulate, and the others are counted in
// TriangulationStats::shared_cell.
//
// A Triangulator is not thread-safe (one per thread: add_stripe uses a scratch buffer).
//
// Rejected (left NaN): columns outside the image, rows outside the image, rays meeting the laser plane at
// less than min_ray_plane_angle_deg (grazing: the depth is ill-conditioned), hits behind the camera or
// farther than max_range_mm.
#include <cstdint>
#include <span>
#include <vector>

#include "common/calibration.hpp"
#include "common/messages.hpp"
#include "host/io/organized_cloud.hpp"
#include "host/io/scan.hpp"

namespace fs::host {

struct TriangulationOptions {
  double min_ray_plane_angle_deg = 3.0;  // grazing rejection: angle between viewing ray and laser plane
  double max_range_mm = 5000.0;          // reject hits farther from the camera centre
  bool use_measured_position = false;    // plane from StripeHeader::measured_position instead of step_index
  // Stripe smoothing: each point's column is replaced by a local straight-line fit (least squares) over the
  // stripe points within +-smooth_half_window rows, not crossing a jump of more than smooth_max_jump_px
  // between adjacent rows (depth edges). On planar faces this cuts the extraction noise by ~sqrt(2w+1)
  // (hw-sim default noise: 0.12 -> ~0.06 mm RMS); at creases it biases a few rows slightly. 0 = off.
  std::uint32_t smooth_half_window = 2;
  float smooth_max_jump_px = 1.0f;
  // What configure() may allocate: camera size (ray table), step count and grid (ScanLimits::check_camera).
  ScanLimits limits;
};

struct TriangulationStats {
  std::uint64_t points = 0;        // triangulated
  std::uint64_t out_of_image = 0;  // row/column outside the sensor, or a step outside the scan
  std::uint64_t grazing = 0;       // ray nearly parallel to the laser plane
  std::uint64_t out_of_range = 0;  // behind the camera or beyond max_range_mm
  // Triangulated but not kept: another point of the same stripe in the same image row (one cell per row and
  // step) was brighter, or as bright and earlier. points + out_of_image + grazing + out_of_range +
  // shared_cell = the stripe points.
  std::uint64_t shared_cell = 0;
};

class Triangulator {
 public:
  Triangulator() = default;
  explicit Triangulator(const ScannerCalibration& calibration, const TriangulationOptions& options = {}) {
    configure(calibration, options);
  }
  // Precomputes the ray table and step planes (allocates; call once per calibration). Reconfiguring with the
  // same camera model only recomputes the planes. Throws fs::Error ("calibration: camera W x H needs a ray
  // table of ~N, above the memory budget ...") when options.limits refuse the camera or the grid.
  void configure(const ScannerCalibration& calibration, const TriangulationOptions& options = {});
  const ScannerCalibration& calibration() const { return calib_; }
  const TriangulationOptions& options() const { return options_; }
  bool configured() const { return configured_; }
  // Frees the ray table, the planes and the scratch buffers; the next triangulate() configures again (call
  // after a scan whose camera was larger than the usual one, then malloc_trim(0): release_scan_memory).
  void release();
  // Heap bytes held by the tables and scratch buffers.
  std::uint64_t table_bytes() const;

  // Sizes `out` to step_count x camera.height, all NaN, viewpoint = camera centre.
  void begin(OrganizedCloud& out) const;
  // Triangulates one stripe into its column of `out` (prepared by begin()).
  void add_stripe(const msg::StripeHeader& header, std::span<const msg::StripePoint> points,
                  OrganizedCloud& out, TriangulationStats& stats) const;
  // begin() + every stripe of the scan (reconfigures first if the scan's calibration differs).
  TriangulationStats triangulate(const Scan& scan, OrganizedCloud& out);

  // One point (double precision, no tables): the reference the fast path is tested against.
  static bool triangulate_point(const ScannerCalibration& calibration, double step, double row, double col,
                                double cos_min, Vec3& out);

 private:
  struct Ray {
    float x, y, z;
  };
  struct StepPlane {
    float nx, ny, nz, e;
  };
  StepPlane plane_for(double step) const;
  // Smoothed columns of a stripe in smoothed_, or nullptr when smoothing is off / not applicable.
  const float* smooth_columns(std::span<const msg::StripePoint> points) const;

  ScannerCalibration calib_;
  TriangulationOptions options_;
  bool configured_ = false;
  std::uint32_t cols_ = 0, rows_ = 0;
  std::vector<Ray> rays_;                // rows_ x (cols_ + 1)
  std::vector<StepPlane> planes_;        // step_count
  mutable std::vector<float> smoothed_;  // per-stripe scratch (kMaxStripePoints, grown if ever needed)
  // Per image row: the stripe (stamp) whose point the row's cell holds, and that point's peak.
  mutable std::vector<std::uint32_t> row_stamp_;
  mutable std::vector<std::uint16_t> row_peak_;
  mutable std::uint32_t stamp_ = 0;
  float sin2_min_ = 0.0f;
  float max_range2_ = 0.0f;
  Eigen::Vector3f centre_ = Eigen::Vector3f::Zero();
};

bool same_camera(const CameraModel& a, const CameraModel& b);
bool same_calibration(const ScannerCalibration& a, const ScannerCalibration& b);

}  // namespace fs::host
