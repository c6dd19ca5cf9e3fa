// Recognizer step 1 (thesis ch. 3.5, 9): per scan, segmentation and scene PFRG with the table absorbed into
// the supernode, the matching parameters and by-id tables, and the sample sets verification looks at.
#include <algorithm>

#include "host/recognize/recognizer_impl.hpp"
#include "host/recognize/scene_prep.hpp"
#include "host/segment/row_thinning.hpp"

namespace fs::host::rec {

namespace {

// The recognizer's overrides of RecognizeParams::match (assigned in place per scan: no allocation).
void override_match(const RecognizeParams& params, match::MatchParams& m) {
  m.max_states = std::min<std::int64_t>(params.match.max_states, params.max_states);
  m.th_minlevel = params.min_level;
  if (params.max_solutions > 0) m.max_solutions = params.max_solutions;
  if (params.area_cost >= 0) m.alpha = params.area_cost;
  if (params.rigidity_pairs) m.rigidity_pairs = true;
  if (params.rigidity_deg > 0) m.th_omega_deg = params.rigidity_deg;
  if (params.match_area_ratio > 0) {
    m.th_area_ratio = params.match_area_ratio;
    m.th_area_slack_mm2 = params.match_area_slack_mm2;
    m.th_area_fold_deg = std::min(params.match_area_fold_deg, match::kAreaFoldMaxDeg);
  }
}

}  // namespace

match::MatchParams match_params(const RecognizeParams& params) {
  match::MatchParams m = params.match;
  override_match(params, m);
  return m;
}

using detail::Clock;
using detail::ms_since;

void Recognizer::Impl::reset_output(Recognition& out) {
  // The reported objects' buffers go back to the spare pool (swapped, never freed), see spare_objects.
  for (std::size_t k = 0; k < out.objects.size(); ++k) std::swap(out.objects[k], spare_objects[k]);
  out.objects.clear();
  out.stats = RecognizeStats{};
  out.note.clear();
}

bool Recognizer::Impl::prepare_scene(Recognizer& rz, const OrganizedCloud& cloud, const Plane* table_hint,
                                     Recognition& out) {
  const RecognizeParams& params = rz.params_;
  auto t0 = Clock::now();
  std::uint32_t row_step = 1;
  // (A cloud whose points do not fill its grid goes to the segmenter, which says so.)
  if (params.segment_row_step == 2 && cloud.organized &&
      cloud.points.size() == std::size_t{cloud.width} * cloud.height) {
    const Eigen::Vector2d grid = grid_spacing_mm(cloud);
    row_step = seg::row_step_for(grid.x(), grid.y());
  }
  if (row_step > 1) {
    seg::thin_rows(cloud, row_step, rz.thin_cloud_);
    rz.thin_segmenter_.segment(rz.thin_cloud_, rz.thin_seg_);
    // A face that few rows reach (turned along the stripe) loses half of them: every row then.
    if (seg::rows_sparse_somewhere(rz.thin_seg_))
      row_step = 1;
    else
      seg::spread_rows(cloud, row_step, rz.thin_seg_, rz.seg_);
  }
  if (row_step == 1) {
    rz.segmenter_.segment(cloud, rz.seg_);
  }
  out.stats.segment_ms = ms_since(t0);
  out.stats.segment_row_step = static_cast<int>(row_step);
  t0 = Clock::now();
  rz.pfrg_builder_.build(rz.seg_, rz.scene_);
  out.stats.regions = static_cast<int>(rz.seg_.regions.size());
  out.stats.known_regions = static_cast<int>(rz.seg_.known_count());
  have_table = false;
  if (params.remove_table) {
    out.stats.table_removed = remove_table(rz.scene_, table_hint, cloud.viewpoint, params.table_angle_deg,
                                           params.table_dist_mm, &table) >= 0;
    have_table = out.stats.table_removed;
  }
  support_tol = params.support_tol_mm;
  support_radius = params.support_radius_mm;
  unsupported_factor = params.unsupported_factor;
  support_hidden_below = params.support_hidden_below;
  hidden_below_min_faces = params.hidden_below_min_faces;
  hidden_below_min_fit = params.hidden_below_min_fit;
  hidden_below_min_rays = params.hidden_below_min_rays;
  support_own_plane = params.support_own_plane_mm;
  table_snap = params.table_snap_mm;
  table_snap_slack = params.table_snap_slack;
  out.stats.pfrg_ms = ms_since(t0);
  int known_nodes = 0;
  for (const auto& n : rz.scene_.nodes) known_nodes += n.supernode ? 0 : 1;
  out.stats.scene_nodes = known_nodes;
  out.stats.scene_arcs = static_cast<int>(rz.scene_.arcs.size());
  out.stats.references = static_cast<int>(rz.library_.models.size());
  if (known_nodes == 0) {
    out.note = "no planar face found in the scene (besides the table)";
    return false;
  }
  return true;
}

// Matching parameters: the preset with the recognizer's overrides; the by-id tables of the scene graph.
Recognizer::Impl::Scan Recognizer::Impl::prepare_matching(Recognizer& rz, const OrganizedCloud& cloud) {
  const RecognizeParams& params = rz.params_;
  const Pfrg& graph = rz.scene_;
  Scan scan;
  scene = &graph;
  library = &rz.library_;
  mparams = params.match;
  override_match(params, mparams);
  mparams_small = mparams;
  scan.min_part = params.min_level;
  scan.small_parts = params.small_part_min_level > 0 && params.small_part_min_level < params.min_level;
  if (scan.small_parts) {
    scan.min_part = params.small_part_min_level;
    mparams_small.th_minlevel = params.small_part_min_level;
  }
  mparams_second = mparams;
  mparams_small_second = mparams_small;
  mparams_second.max_states =
      std::min(mparams.max_states, std::max<std::int64_t>(params.second_search_states, 1));
  mparams_small_second.max_states = mparams_second.max_states;
  int max_id = 0;
  for (const auto& n : graph.nodes) max_id = std::max(max_id, n.id);
  scene_index.assign(static_cast<std::size_t>(max_id) + 1, -1);
  for (std::size_t i = 0; i < graph.nodes.size(); ++i)
    scene_index[static_cast<std::size_t>(graph.nodes[i].id)] = static_cast<int>(i);
  node_used.assign(static_cast<std::size_t>(max_id) + 1, 0);
  lone_tried.assign(static_cast<std::size_t>(max_id) + 1, 0);
  mark_supernodes(graph);
  if (cell_owner.size() < cloud.points.size()) cell_owner.resize(cloud.points.size(), -1);
  return scan;
}

// The measured points verification looks at (built once per scan), counted per segmentation region.
void Recognizer::Impl::prepare_samples(Recognizer& rz, const OrganizedCloud& cloud, RecognizeStats& stats) {
  const seg::Segmentation& segmentation = rz.seg_;
  auto t_samples = Clock::now();
  const Eigen::Vector2d grid = grid_spacing_mm(cloud);
  const VerifyParams& vp = rz.params_.verify;
  coarse.build(cloud, sample_steps(grid, 2 * vp.sample_step, 2.0 * vp.sample_spacing_mm));
  fine.build(cloud, sample_steps(grid, vp.sample_step, vp.sample_spacing_mm));
  if (rz.params_.max_screened > 0)
    screen.build(cloud, sample_steps(grid, 4 * vp.sample_step, 4.0 * vp.sample_spacing_mm));
  labels = &segmentation.labels;
  auto count_regions = [&](const SampleSet& set, std::vector<std::uint32_t>& counts) {
    counts.assign(segmentation.regions.size(), 0);
    for (std::uint32_t cell : set.cells()) {
      const std::int32_t r = cell < segmentation.labels.size() ? segmentation.labels[cell] : -1;
      if (r >= 0 && static_cast<std::size_t>(r) < counts.size()) ++counts[static_cast<std::size_t>(r)];
    }
  };
  count_regions(coarse, region_coarse);
  count_regions(fine, region_fine);
  if (rz.params_.max_screened > 0) count_regions(screen, region_screen);
  stats.verify_ms += ms_since(t_samples);
  nhyp = 0;  // no part: no hypothesis (not last scan's)
}

}  // namespace fs::host::rec
