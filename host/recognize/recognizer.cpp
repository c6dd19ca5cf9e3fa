// Recognition driver (thesis ch. 8-9; see README.md): the working memory sized once, and recognize() as the
// sequence of its steps (Recognizer::Impl, recognizer_impl.hpp).
#include "host/recognize/recognizer.hpp"

#include <algorithm>

#include "common/error.hpp"
#include "host/recognize/recognizer_impl.hpp"

namespace fs::host::rec {

using detail::Clock;
using detail::kMaxMatches;
using detail::ms_since;

Recognizer::Impl::Impl(const Library& lib, const RecognizeParams& p, int threads)
    : pool(threads), batch(std::min(kMatchBatch, lib.models.size())) {
  match::MatcherLimits limits;
  limits.max_states = std::max<std::int64_t>(p.max_states, 16);
  limits.max_reported = std::max(p.solutions_per_model, 1);
  for (int w = 0; w < pool.threads(); ++w) {
    matchers.push_back(std::make_unique<match::InexactMatcher>(limits));
    verifiers.emplace_back(p.verify);
  }
  geometry.reserve(lib.models.size());
  for (const Model& m : lib.models) geometry.emplace_back(m);
  near_sym.resize(lib.models.size());
  if (p.near_symmetry_share > 0) {
    NearSymmetryParams np;
    np.min_share = p.near_symmetry_share;
    for (std::size_t k = 0; k < lib.models.size(); ++k) near_sym[k] = near_symmetries(lib.models[k], np);
  }
  if (p.symmetry_roots) {
    search_roots.resize(lib.models.size());
    for (std::size_t k = 0; k < lib.models.size(); ++k) {
      const Model& m = lib.models[k];
      const std::vector<int> rep = face_orbit_representatives(m);
      for (std::size_t f = 0; f < m.graph.nodes.size() && f < static_cast<std::size_t>(match::kMaxNodes); ++f)
        if (f >= rep.size() || rep[f] == static_cast<int>(f)) search_roots[k].set(static_cast<int>(f));
    }
  }
  second_search = p.second_search;
  second_search_min_level = p.second_search_min_level;
  placement = p.placement;
  worker_pairs.resize(static_cast<std::size_t>(pool.threads()));
  for (auto& w : worker_pairs) w.reserve(256);
  worker_later.resize(static_cast<std::size_t>(pool.threads()));
  for (auto& w : worker_later) w.reserve(static_cast<std::size_t>(limits.max_reported));
  for (auto& pm : batch) {
    pm.slots.resize(static_cast<std::size_t>(std::max(p.solutions_per_model, 0)));
    if (second_search) pm.slots.resize(2 * pm.slots.size());  // the second search's solutions too
    for (auto& s : pm.slots) {
      s.path.reserve(kMaxMatches);
      s.matches.reserve(kMaxMatches);
    }
  }
  // The search solutions (all of every reference's, of both searches of a part, up to max_hypotheses), plus
  // room for the single-face hypotheses of kLoneFaceRoom lone faces.
  max_solutions = std::min(lib.models.size() * (p.second_search ? 2 : 1) *
                               static_cast<std::size_t>(std::max(p.solutions_per_model, 0)),
                           static_cast<std::size_t>(p.hypothesis_pool(lib.models.size())));
  const std::size_t max_h =
      max_solutions + kLoneFaceRoom * static_cast<std::size_t>(std::max(p.single_face_max, 0));
  hyps.resize(max_h);
  worst.reserve(max_solutions);
  use_arc_index = p.arc_index;
  if (use_arc_index) {
    if (lib.index_describes_models()) {
      arc_index = &lib.index;
    } else {
      own_arc_index = lib.index_of_models();
      arc_index = &own_arc_index;
    }
  }
  part_mask.reserve(lib.models.size());
  for (auto& h : hyps) {
    h.matches.reserve(kMaxMatches);
    h.path.reserve(kMaxMatches);
  }
  order.reserve(max_h);
  reseated.reserve(max_h);
  dropped.reserve(max_h);
  raw_confidence.reserve(max_h);
  picked.reserve(max_h);
  waiting.reserve(max_h);
  order_copy.reserve(max_h);
  coarse_order.reserve(max_h);
  refined.reserve(max_h);
  deferred.reserve(max_h);
  hidden_wait.reserve(max_h);
  face_cover.reserve(kMaxNodeIds);
  face_best.reserve(kMaxNodeIds);
  alive.reserve(max_h);
  pairs.reserve(256);
  node_used.reserve(kMaxNodeIds);
  scene_index.reserve(kMaxNodeIds);
}

Recognizer::Recognizer(const Library& library, const RecognizeParams& params, std::size_t max_cells)
    : library_(library),
      params_(params),
      segmenter_(params.segment, seg::SegmentLimits{max_cells, Impl::kMaxRegions, 32768}),
      // Sized only when used. The same parameters: a known region needs min_region_cells on every other row
      // too (with half as many, strips of one row, points on a line, would count as faces).
      thin_segmenter_(params.segment, params.segment_row_step == 2
                                          ? seg::SegmentLimits{max_cells / 2 + 4096, Impl::kMaxRegions, 32768}
                                          : seg::SegmentLimits{1, 1, 1}),
      pfrg_builder_(Impl::kMaxRegions, 32768) {
  if (params.segment_row_step != 1 && params.segment_row_step != 2)
    throw Error("recognize: segment_row_step is " + std::to_string(params.segment_row_step) +
                ", expected 1 (every row) or 2 (every other row)");
  segmenter_.prepare(seg_);
  if (params.segment_row_step == 2) {
    thin_segmenter_.prepare(thin_seg_);
    thin_cloud_.points.reserve(max_cells / 2 + 4096);  // grids up to 8,192 columns wide
  }
  pfrg_builder_.prepare(scene_);
  impl_ = std::make_unique<Impl>(library, params_, params.threads);
  impl_->cell_owner.assign(max_cells, -1);
  impl_->coarse.reserve(max_cells);
  impl_->fine.reserve(max_cells);
  impl_->screen.reserve(max_cells);
  impl_->parts.resize(Impl::kMaxParts);
  impl_->part_faces.resize(Impl::kMaxParts);
  for (Pfrg& part : impl_->parts) {
    part.nodes.reserve(256);
    part.arcs.reserve(2048);
    part.name.reserve(64);
  }
  impl_->uf.reserve(Impl::kMaxNodeIds);
  impl_->lone_faces.reserve(Impl::kMaxNodeIds);
  impl_->lone_tried.reserve(Impl::kMaxNodeIds);
  impl_->rest.nodes.reserve(Impl::kMaxNodeIds);
  impl_->rest_super_arc.reserve(Impl::kMaxNodeIds);
  impl_->super_by_id.reserve(Impl::kMaxNodeIds);
  impl_->rest.arcs.reserve(32768);
  impl_->rest.name.reserve(64);
  impl_->part_of.reserve(Impl::kMaxNodeIds);
  impl_->comp_size.reserve(Impl::kMaxNodeIds);
  impl_->stamp.reserve(Impl::kMaxNodeIds);
  impl_->bfs.reserve(Impl::kMaxNodeIds + 1);
  impl_->adj_start.reserve(Impl::kMaxNodeIds + 1);
  impl_->adj.reserve(2 * 32768);
  impl_->max_part_faces = params.max_part_faces;
  // Fine samples of a grid of max_cells cells: at most ceil(h/s) * ceil(w/s) <= cells/s^2 + cells/s + 1.
  const std::size_t step = static_cast<std::size_t>(std::max(1, params.verify.sample_step));
  const std::size_t max_samples = max_cells / (step * step) + max_cells / step + 1;
  impl_->slot_cells.resize(static_cast<std::size_t>(std::max(params.max_refined, 1)));
  for (auto& b : impl_->slot_cells) b.reserve(max_samples);
  impl_->slot_owner.reserve(impl_->slot_cells.size());
  std::size_t max_faces = 0;  // the largest model's front-face list
  for (const Model& m : library_.models) max_faces = std::max(max_faces, m.faces.size());
  for (auto& v : impl_->verifiers) v.reserve(max_samples, max_faces);
  impl_->hull.reserve(max_samples);
  impl_->hull_scratch.reserve(2 * max_samples);
  result_.objects.reserve(static_cast<std::size_t>(std::max(params.max_objects, 1)));
  impl_->spare_objects.resize(result_.objects.capacity());
  for (Hypothesis& h : impl_->spare_objects) {
    h.matches.reserve(kMaxMatches);
    h.path.reserve(kMaxMatches);
    h.inlier_cells.reserve(max_samples);
  }
  result_.note.reserve(512);
  impl_->conflict_cells.reserve(result_.objects.capacity());
  impl_->conflict_faces.reserve(result_.objects.capacity());
  impl_->conflict_depth.reserve(result_.objects.capacity());
  impl_->conflict_share.reserve(result_.objects.capacity());
}

int RecognizeParams::hypothesis_pool(std::size_t models) const {
  if (max_hypotheses > 0) return max_hypotheses;
  const std::size_t want = models * static_cast<std::size_t>(kAutoSolutionsPerModel);
  return static_cast<int>(std::clamp<std::size_t>(want, kAutoMinHypotheses, kAutoMaxHypotheses));
}

Recognizer::~Recognizer() = default;

const Recognition& Recognizer::recognize(const OrganizedCloud& cloud, const Plane* table) {
  Impl& im = *impl_;
  const auto t_start = Clock::now();
  Recognition& out = result_;
  im.reset_output(out);
  // 1. Segmentation and scene PFRG.
  if (!im.prepare_scene(*this, cloud, table, out)) {
    out.stats.total_ms = ms_since(t_start);
    return out;
  }
  Impl::Scan scan = im.prepare_matching(*this, cloud);
  const HypothesisContext hc{library_,        scene_,  im.scene_index,
                             cloud.viewpoint, params_, cloud.scanner ? &*cloud.scanner : nullptr};
  im.prepare_samples(*this, cloud, out.stats);
  // Rounds: the scene graph, then (beyond the thesis) the faces no accepted object explains, searched again
  // with TH_minlevel lowered to small_part_min_level (an object showing two faces next to another object),
  // with single-face hypotheses for faces that border no unexplained face; until a round accepts nothing new.
  const int rounds = std::max(1, params_.rounds);
  for (int round = 0; round < rounds; ++round) {
    // 2. Match the scene (or what is left of it) against every reference.
    const Pfrg* graph = im.split_scene(*this, scan, round, cloud.viewpoint, out.stats);
    if (!graph) break;
    im.match_references(library_, round, out.stats);
    // 3. Hypotheses: pose, expansion, compatible merge, single-face hypotheses.
    im.make_hypotheses(*this, hc, *graph, scan, out.stats);
    if (im.nhyp == 0) {
      if (round > 0 && im.raised_waiting == 0) break;
      continue;
    }
    // 4. Low-level verification of the most plausible hypotheses.
    im.verify_hypotheses(*this, hc, cloud, out.stats);
    // 5. Recognition (ch. 9.4): greedy extraction of the compatible set that holds the best solution.
    // A round that accepts nothing ends the search, unless lone faces wait for their raised placements.
    if (!im.accept_objects(*this, scan, round, out) && im.raised_waiting == 0) break;
  }
  im.finish_report(*this, scan, out);
  out.stats.total_ms = ms_since(t_start);
  return out;
}

const Plane* Recognizer::table() const { return impl_->have_table ? &impl_->table : nullptr; }

std::vector<const Hypothesis*> Recognizer::candidates() const {
  std::vector<const Hypothesis*> out;
  for (std::size_t i : impl_->order) out.push_back(&impl_->hyps[i]);
  return out;
}

std::vector<const Hypothesis*> Recognizer::all_hypotheses() const {
  std::vector<const Hypothesis*> out;
  for (std::size_t i = 0; i < impl_->nhyp; ++i)
    if (i < impl_->alive.size() && impl_->alive[i]) out.push_back(&impl_->hyps[i]);
  return out;
}

void Recognizer::object_labels(const OrganizedCloud& cloud, std::vector<std::int32_t>& labels) const {
  labels.assign(cloud.points.size(), -1);
  if (seg_.labels.size() != cloud.points.size()) return;
  // scene node id = region + 1
  for (std::size_t o = 0; o < result_.objects.size(); ++o) {
    for (const FaceMatch& m : result_.objects[o].matches) {
      const std::int32_t region = m.scene - 1;
      for (std::size_t i = 0; i < seg_.labels.size(); ++i)
        if (seg_.labels[i] == region) labels[i] = static_cast<std::int32_t>(o);
    }
  }
}

}  // namespace fs::host::rec
