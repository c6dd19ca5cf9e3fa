#pragma once
// Region/border representation of an organized grid (thesis ch. 3.5.1): a label per cell, planar regions
// with area (mm^2, from the 3D grid cells), fitted plane (normal toward the viewpoint) and borders between
// regions, to cells without data (NIL) and to the image boundary, with their 3D length (mm).
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/calibration.hpp"

namespace fs::host::seg {

inline constexpr std::int32_t kNil = -1;      // cell without data (NaN point)
inline constexpr std::int32_t kOutside = -2;  // beyond the image boundary (only as a border neighbour)

struct Region {
  std::int32_t id = 0;  // == index in Segmentation::regions
  bool known = false;   // planar with enough support: attributes (area, plane) are meaningful
  std::uint32_t cells = 0;
  double area = 0.0;                                // mm^2, sum of the 3D cell areas
  Plane plane;                                      // n . x = d, n toward the viewpoint
  Vec3 centroid = Vec3::Zero();                     // mm
  double rms = 0.0;                                 // rms point-to-plane distance, mm
  Eigen::Vector2f pixel = Eigen::Vector2f::Zero();  // mean (col, row) of its cells (for pictures)
};

// All border segments between one pair of neighbours, summed. a >= 0 is a region; b is a region > a,
// kNil or kOutside.
struct Border {
  std::int32_t a = 0, b = 0;
  double length = 0.0;           // mm (3D)
  std::uint32_t edges = 0;       // number of grid cell edges on this border
  std::uint32_t continuous = 0;  // edges whose two cells are depth-continuous (0 for a pure jump edge)
};

struct Segmentation {
  std::uint32_t width = 0, height = 0;
  std::vector<std::int32_t> labels;  // per cell (row-major): region id or kNil
  std::vector<Region> regions;
  std::vector<Border> borders;
  bool truncated = false;  // the region / border budget ran out; the rest is left unknown
  double noise_mm = 0.0;   // the scan's estimated depth noise (sigma, mm; 0 = too few samples)
  double dist_mm = 0.0;
  // Median distance of grid neighbours along a row (x: the next column) and a column (y: the next row), mm
  // (0 = too few samples); SegmentParams::jump_spacing_factor scales it into the jump thresholds.
  Eigen::Vector2d spacing_mm = Eigen::Vector2d::Zero();  // the point-to-plane tolerance used:
                                                         // max(dist_abs_mm, dist_noise_factor x noise)

  // Reserves everything for grids up to max_cells and up to max_regions regions (no allocation later).
  void reserve(std::size_t max_cells, std::size_t max_regions, std::size_t max_borders) {
    labels.reserve(max_cells);
    regions.reserve(max_regions);
    borders.reserve(max_borders);
  }
  std::size_t known_count() const {
    std::size_t n = 0;
    for (const auto& r : regions) n += r.known ? 1 : 0;
    return n;
  }
};

}  // namespace fs::host::seg
