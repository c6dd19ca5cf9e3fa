#pragma once
// An organized 3D point grid in millimetres: for laser scans, columns = galvo steps and rows = image rows;
// for PCD/PLY input, the sensor's width x height. NaN x = no data. Memory is reserved once (reserve()) and
// reused: reset() within capacity does not allocate.
//
// An unorganized cloud (a PLY without grid information) is stored as height = 1, width = point count with
// organized = false; consumers that need the grid (segmentation) refuse it with a clear message.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include "common/calibration.hpp"

namespace fs::host {

struct OrganizedCloud {
  std::uint32_t width = 0;              // columns
  std::uint32_t height = 0;             // rows
  std::vector<Eigen::Vector3f> points;  // row-major: index = row * width + col
  std::vector<std::int32_t> labels;     // optional per-point labels (ground truth / dataset), empty if none
  Eigen::Vector3d viewpoint = Eigen::Vector3d::Zero();  // sensor position, same frame as the points
  Eigen::Quaterniond viewpoint_orientation =
      Eigen::Quaterniond::Identity();  // sensor orientation (PCD VIEWPOINT)
  bool organized = true;               // false: points have no grid neighbourhood (height == 1)
  // The scanner that measured it, when known (a .fscan's calibration, hw-sim): where the laser comes from and
  // what the sweep reaches, so that recognition expects surfaces only where the scan could measure them.
  std::optional<ScannerCalibration> scanner;

  void reserve(std::size_t max_points) {
    points.reserve(max_points);
    labels.reserve(max_points);
  }
  void reset(std::uint32_t w, std::uint32_t h, bool with_labels = false) {
    width = w;
    height = h;
    organized = true;
    scanner.reset();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    points.assign(static_cast<std::size_t>(w) * h, Eigen::Vector3f(nan, nan, nan));
    if (with_labels)
      labels.assign(static_cast<std::size_t>(w) * h, -1);
    else
      labels.clear();
  }
  std::size_t size() const { return points.size(); }
  bool has_labels() const { return !labels.empty(); }
  std::size_t index(std::uint32_t row, std::uint32_t col) const { return std::size_t(row) * width + col; }
  const Eigen::Vector3f& at(std::uint32_t row, std::uint32_t col) const { return points[index(row, col)]; }
  Eigen::Vector3f& at(std::uint32_t row, std::uint32_t col) { return points[index(row, col)]; }
  static bool valid(const Eigen::Vector3f& p) { return p.x() == p.x(); }
  std::size_t valid_count() const {
    std::size_t n = 0;
    for (const auto& p : points) n += valid(p) ? 1 : 0;
    return n;
  }
};

}  // namespace fs::host
