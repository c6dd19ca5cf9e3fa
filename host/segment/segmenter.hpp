#pragma once
// Planar segmentation of an organized grid (thesis ch. 2.4, 3.5.1): normals from the grid tangents
// (one-sided at depth jumps; vectorized row kernels in grid_kernels.hpp), depth-continuity bits per cell,
// region growing (normal angle + point-to-plane distance + depth continuity; breadth-first start, then a
// scanline flood fill), edge refinement, plane refit, merge pass of adjacent coplanar regions, boundary
// relabelling (border cells go to the nearer adjacent plane), leftover cells grouped into unknown regions,
// and the border lengths between everything.
//
// Memory: all working buffers are sized once (constructor / reserve()) by the largest grid and the region
// budget; segment() then runs without heap allocation for grids within that size. When the region or border
// budget is exhausted the remaining cells stay unknown and Segmentation::truncated is set.
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "host/io/organized_cloud.hpp"
#include "host/segment/segment_params.hpp"
#include "host/segment/segmentation.hpp"

namespace fs::host::seg {

struct SegmentLimits {
  std::size_t max_cells = 640 * 480;
  std::size_t max_regions = 8192;
  std::size_t max_borders = 32768;
};

class Segmenter {
 public:
  explicit Segmenter(const SegmentParams& params = SegmentParams::laser(), const SegmentLimits& limits = {});

  const SegmentParams& params() const { return params_; }
  const SegmentLimits& limits() const { return limits_; }
  // Grows the buffers (allocates) so that grids of up to max_cells cells fit.
  void reserve(std::size_t max_cells);
  // Reserves `out` for the limits of this segmenter (call once, then reuse `out`).
  void prepare(Segmentation& out) const;

  // Segments `cloud` into `out` (reused). Grids larger than the reserved size grow the buffers first.
  void segment(const OrganizedCloud& cloud, Segmentation& out);

  // Unit normal of cell i (row-major) from the last segment() call (NaN where undefined).
  Eigen::Vector3f normal(std::size_t i) const { return {nx_[i], ny_[i], nz_[i]}; }

 private:
  struct Acc {  // moments relative to origin_ (double)
    double n = 0, sx = 0, sy = 0, sz = 0, sxx = 0, sxy = 0, sxz = 0, syy = 0, syz = 0, szz = 0;
    double area = 0, pc = 0, pr = 0;
    void add(const Eigen::Vector3d& p, double a, double col, double row);
    void merge(const Acc& o);
  };
  struct PlaneF {
    Eigen::Vector3f n = Eigen::Vector3f::UnitZ();
    Eigen::Vector3f c = Eigen::Vector3f::Zero();
  };

  // Median distance of grid neighbours along a row (x) and a column (y) over a subsample (0 = too few).
  Eigen::Vector2d estimate_spacing(const OrganizedCloud& cloud);
  // Robust depth-noise estimate (sigma, mm; 0 = too few samples) from second differences along the grid rows.
  double estimate_noise(const OrganizedCloud& cloud);
  void compute_normals(const OrganizedCloud& cloud);
  void grow_regions(const OrganizedCloud& cloud, Segmentation& out);
  void refine_edges(const OrganizedCloud& cloud);
  void merge_regions(const OrganizedCloud& cloud, Segmentation& out);
  void relabel_borders(const OrganizedCloud& cloud);
  void group_leftovers(const OrganizedCloud& cloud, Segmentation& out);
  void finalize_regions(const OrganizedCloud& cloud, Segmentation& out);
  void compute_borders(const OrganizedCloud& cloud, Segmentation& out);

  // Adds the point moments of `cells` to `a` (relative to origin_; no area / pixel sums).
  void accumulate(Acc& a, const std::uint32_t* cells, std::size_t count) const;
  void accumulate_run(Acc& a, std::size_t first, std::size_t last) const;  // cells first..last (inclusive)
  void fit(const Acc& a, Eigen::Vector3d& n, Eigen::Vector3d& c, double& rms) const;
  void refit(int region);
  // Depth continuity of grid neighbours (kernels::continuous, computed once per scan into cont_): close
  // enough, or (up to jump_max_mm) a step that is not along the viewing ray, i.e. a surface seen at a grazing
  // angle rather than a jump edge.
  float jump_max2_ = 0.f, cos2_jump_ = 1.f;
  // This scan's floor of the squared jump threshold along a row (toward the next column) and a column
  // (toward the next row): (jump_spacing_factor x Segmentation::spacing_mm, at most jump_max_mm)^2.
  float floor2_x_ = 0.f, floor2_y_ = 0.f;
  // This scan's normal span per axis (cells): normal_span, shorter on a coarse grid (SegmentParams).
  int span_x_ = 1, span_y_ = 1;
  Eigen::Vector3f vp_f_ = Eigen::Vector3f::Zero();
  // Border pair table (open addressing); returns the index in out.borders or -1 when full.
  int border_slot(Segmentation& out, std::int32_t a, std::int32_t b);
  void clear_border_table();

  SegmentParams params_;
  SegmentLimits limits_;
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d viewpoint_ = Eigen::Vector3d::Zero();
  std::uint32_t width_ = 0, height_ = 0;
  static constexpr std::size_t kSamples = 32768;  // of the spacing and noise estimates
  double dist_abs_ = 0.0;       // this scan's max(dist_abs_mm, dist_noise_factor * estimate_noise())
  std::vector<float> samples_;  // their scratch

  // per cell (structure of arrays: the normal pass is vectorized); points with NaN = no data
  std::vector<float> px_, py_, pz_, nx_, ny_, nz_;
  std::vector<std::uint8_t> cont_;  // depth-continuity bits toward the 4 grid neighbours
  std::vector<float> area_, lenu_, lenv_, jump2_, dist_;
  // finalize_regions: one row's cell areas inside regions (-1: a border cell) and their tangents' lengths^2
  std::vector<float> row_area_, row_lu_, row_lv_;
  std::vector<std::uint8_t> state_;
  std::vector<std::int32_t> lab_;
  std::vector<std::uint32_t> queue_;
  std::vector<std::uint32_t> pend_cell_;
  std::vector<std::int32_t> pend_label_;
  // per region
  std::vector<Acc> acc_;
  std::vector<PlaneF> plane_;
  std::vector<std::int32_t> parent_, remap_;
  std::vector<std::uint8_t> grown_;
  std::size_t region_count_ = 0;
  // border pair table
  std::vector<std::uint64_t> bkey_;
  std::vector<std::int32_t> bval_;
  // border edges (cell * 2 + {0: right, 1: down}) and their border index, for the straight-edge lengths
  std::vector<std::uint32_t> edge_cell_;
  std::vector<std::int32_t> edge_border_;
  struct LineInfo {
    Eigen::Vector3f dir = Eigen::Vector3f::Zero();
    float tmin = 0, tmax = 0, bin = 0;
    std::int32_t offset = -1, count = 0;
  };
  std::vector<LineInfo> line_;
  std::vector<std::uint8_t> bins_;
  void straight_border_lengths(const OrganizedCloud& cloud, Segmentation& out, std::size_t nedges);
};

}  // namespace fs::host::seg
