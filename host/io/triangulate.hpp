#pragma once
// Laser-stripe triangulation: the camera ray through each undistorted sub-pixel stripe point, intersected
// with the laser plane of its galvo step, gives a 3D point (mm, world frame) at (row = image row,
// column = step - first_step) of an OrganizedCloud.
//
// Speed: configure() precomputes, for every image row and integer column, the world-frame direction of the
// undistorted ray R_world_cam * (x_n, y_n, 1) (linear in the pixel apart from distortion, so linear
// interpolation between neighbouring columns is accurate to ~1e-9 rad), and per galvo step the plane normal
// n_k and e_k = d_k - n_k . C. A point then costs an interpolation, two dot products and a division.
// Memory: rows x (cols + 1) x 12 bytes (16 MB for 1280 x 1024), allocated by configure(); triangulating a
// scan into a cloud whose capacity suffices allocates nothing.
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

namespace fs::host {

class Scan;

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
};

struct TriangulationStats {
  std::uint64_t points = 0;        // triangulated
  std::uint64_t out_of_image = 0;  // row/column outside the sensor, or a step outside the scan
  std::uint64_t grazing = 0;       // ray nearly parallel to the laser plane
  std::uint64_t out_of_range = 0;  // behind the camera or beyond max_range_mm
};

class Triangulator {
 public:
  Triangulator() = default;
  explicit Triangulator(const ScannerCalibration& calibration, const TriangulationOptions& options = {}) {
    configure(calibration, options);
  }
  // Precomputes the ray table and step planes (allocates; call once per calibration). Reconfiguring with the
  // same camera model only recomputes the planes.
  void configure(const ScannerCalibration& calibration, const TriangulationOptions& options = {});
  const ScannerCalibration& calibration() const { return calib_; }

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
  float sin2_min_ = 0.0f;
  float max_range2_ = 0.0f;
  Eigen::Vector3f centre_ = Eigen::Vector3f::Zero();
};

bool same_camera(const CameraModel& a, const CameraModel& b);
bool same_calibration(const ScannerCalibration& a, const ScannerCalibration& b);

}  // namespace fs::host
