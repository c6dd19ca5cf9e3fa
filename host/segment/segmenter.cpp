// Segmenter driver: buffers sized up front, per-scan setup and the stage sequence of segment() (the stages
// live in normals.cpp, plane_fit.cpp, grow.cpp, merge.cpp, regions.cpp and borders.cpp; see README.md).
#include "host/segment/segmenter.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "common/error.hpp"
#include "host/segment/segmenter_impl.hpp"

namespace fs::host::seg {

using namespace detail;

Segmenter::Segmenter(const SegmentParams& params, const SegmentLimits& limits)
    : params_(params), limits_(limits) {
  acc_.resize(limits_.max_regions);
  plane_.resize(limits_.max_regions);
  parent_.resize(limits_.max_regions);
  remap_.resize(limits_.max_regions);
  grown_.resize(limits_.max_regions);
  const std::size_t cap = next_pow2(limits_.max_borders * 2 + 16);
  bkey_.assign(cap, ~std::uint64_t{0});
  bval_.assign(cap, -1);
  line_.resize(limits_.max_borders);
  reserve(limits_.max_cells);
}

void Segmenter::reserve(std::size_t n) {
  if (area_.size() >= n) return;
  for (auto* v : {&px_, &py_, &pz_, &nx_, &ny_, &nz_}) v->resize(n);
  cont_.resize(n);
  area_.resize(n);
  lenu_.resize(n);
  lenv_.resize(n);
  jump2_.resize(n);
  dist_.resize(n);
  state_.resize(n);
  lab_.resize(n);
  queue_.resize(n);
  pend_cell_.resize(n);
  pend_label_.resize(n);
  // finalize_regions' rows: only grids of 3 rows or more have an inner row, at most n / 3 cells wide
  for (auto* v : {&row_area_, &row_lu_, &row_lv_}) v->resize(n / 3 + 1);
  edge_cell_.resize(2 * n + 8);
  edge_border_.resize(2 * n + 8);
  bins_.resize(n + 1024);
  samples_.reserve(kSamples);
  limits_.max_cells = std::max(limits_.max_cells, n);
}

void Segmenter::prepare(Segmentation& out) const {
  out.reserve(limits_.max_cells, limits_.max_regions, limits_.max_borders);
}

void Segmenter::segment(const OrganizedCloud& cloud, Segmentation& out) {
  const std::size_t n = std::size_t(cloud.width) * cloud.height;
  if (cloud.points.size() != n) {
    throw Error("segment: organized cloud has " + std::to_string(cloud.points.size()) +
                " points, expected width " + std::to_string(cloud.width) + " x height " +
                std::to_string(cloud.height));
  }
  if (!cloud.organized)
    throw Error(
        "segment: the cloud has no grid (a PLY without obj_info num_cols/num_rows or a range_grid "
        "element): segmentation needs an organized cloud");
  if (!cloud.viewpoint.allFinite()) throw Error("segment: viewpoint is not finite");
  reserve(n);
  width_ = cloud.width;
  height_ = cloud.height;
  viewpoint_ = cloud.viewpoint;
  vp_f_ = viewpoint_.cast<float>();
  jump_max2_ = float(params_.jump_max_mm * params_.jump_max_mm);
  const double cj = std::cos(params_.jump_angle_deg * kPi / 180.0);
  cos2_jump_ = float(cj * cj);
  out.width = cloud.width;
  out.height = cloud.height;
  out.truncated = false;
  out.regions.clear();
  out.borders.clear();
  origin_.setZero();
  for (std::size_t i = 0; i < n; ++i) {
    if (finite(cloud.points[i])) {
      origin_ = cloud.points[i].cast<double>();
      break;
    }
  }
  region_count_ = 0;
  out.spacing_mm = estimate_spacing(cloud);
  // capped at jump_max_mm: on a grid that sparse a jump cannot be told from a slope anyway
  const Eigen::Vector2d floor = (params_.jump_spacing_factor * out.spacing_mm).cwiseMin(params_.jump_max_mm);
  floor2_x_ = float(floor.x() * floor.x());
  floor2_y_ = float(floor.y() * floor.y());
  out.noise_mm = estimate_noise(cloud);
  // Per axis (x along a row: the next column; y along a column: the next row), the normals' span reaches at
  // most normal_span_mm, or farther where the depth noise needs it: a tangent reaching r mm turns the normal
  // by about noise / r, kept within half the seed angle.
  const int span = std::max(1, params_.normal_span);
  const double reach =
      std::max(params_.normal_span_mm, out.noise_mm / std::tan(params_.seed_angle_deg * kPi / 360.0));
  auto axis_span = [&](double spacing) {
    if (params_.normal_span_mm <= 0.0 || spacing <= 0.0 || spacing * span <= reach) return span;
    return std::clamp(int(reach / spacing), 1, span);
  };
  span_x_ = axis_span(out.spacing_mm.x());
  span_y_ = axis_span(out.spacing_mm.y());
  dist_abs_ = std::max(params_.dist_abs_mm, params_.dist_noise_factor * out.noise_mm);
  out.dist_mm = dist_abs_;
  compute_normals(cloud);
  grow_regions(cloud, out);
  refine_edges(cloud);
  merge_regions(cloud, out);
  relabel_borders(cloud);
  group_leftovers(cloud, out);
  finalize_regions(cloud, out);
  compute_borders(cloud, out);
}

}  // namespace fs::host::seg
