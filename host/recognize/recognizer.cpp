#include "host/recognize/recognizer.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>

#include "host/recognize/pose.hpp"
#include "host/recognize/hypotheses.hpp"
#include "host/recognize/scene_prep.hpp"
#include "host/recognize/worker_pool.hpp"

namespace fs::host::rec {

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// One reference's kept solutions (buffers reused across scans).
struct SolutionSlot {
  std::vector<int> path;
  std::vector<match::NodeMatch> matches;
  Mat3 rotation = Mat3::Identity();
  double cost = 0, rotfit = 0;
  int level = 0, rank = 0;
  bool degenerate = false;
};

struct ModelSlots {
  std::vector<SolutionSlot> slots;
  int count = 0;
  std::int64_t states = 0;
};

}  // namespace

struct Recognizer::Impl {
  explicit Impl(const Library& lib, const RecognizeParams& p, int threads)
      : pool(threads), per_model(lib.models.size()) {
    match::MatcherLimits limits;
    limits.max_states = std::max<std::int64_t>(p.max_states, 16);
    limits.max_reported = std::max(p.solutions_per_model, 1);
    for (int w = 0; w < pool.threads(); ++w) {
      matchers.push_back(std::make_unique<match::InexactMatcher>(limits));
      verifiers.emplace_back(p.verify);
    }
    geometry.reserve(lib.models.size());
    for (const Model& m : lib.models) geometry.emplace_back(m);
    for (auto& pm : per_model) {
      pm.slots.resize(static_cast<std::size_t>(p.solutions_per_model));
      for (auto& s : pm.slots) {
        s.path.reserve(64);
        s.matches.reserve(64);
      }
    }
    const std::size_t max_h = lib.models.size() * static_cast<std::size_t>(p.solutions_per_model);
    hyps.resize(max_h);
    for (auto& h : hyps) {
      h.matches.reserve(64);
      h.path.reserve(64);
      h.inlier_cells.reserve(4096);
    }
    order.reserve(max_h);
    alive.reserve(max_h);
    pairs.reserve(256);
    node_used.reserve(8192);
    scene_index.reserve(8192);
    accepted.reserve(64);
  }

  WorkerPool pool;
  std::vector<std::unique_ptr<match::InexactMatcher>> matchers;
  std::vector<Verifier> verifiers;
  std::vector<ModelGeometry> geometry;
  std::vector<ModelSlots> per_model;
  std::vector<Hypothesis> hyps;     // pool; the first nhyp are live this scan
  std::size_t nhyp = 0;
  std::vector<std::size_t> order;
  std::vector<char> alive;
  std::vector<PlanePair> pairs;
  std::vector<char> node_used;      // by scene node id
  std::vector<int> scene_index;     // scene node id -> index in scene.nodes (-1)
  std::vector<std::int32_t> cell_owner;
  std::vector<std::size_t> accepted;
  // Matching context.
  const Pfrg* scene = nullptr;
  const Library* library = nullptr;
  match::MatchParams mparams;
  // Verification context.
  SampleSet coarse, fine;
  bool refine_phase = false;
  // Samples per segmentation region (coarse / fine), to measure how much of its matched regions a hypothesis
  // explains.
  std::vector<std::uint32_t> region_coarse, region_fine;
  std::vector<std::uint32_t> region_hits;
  const std::vector<std::int32_t>* labels = nullptr;
};

Recognizer::Recognizer(const Library& library, const RecognizeParams& params, std::size_t max_cells)
    : library_(library),
      params_(params),
      segmenter_(params.segment, seg::SegmentLimits{max_cells, 8192, 32768}),
      pfrg_builder_(8192, 32768) {
  segmenter_.prepare(seg_);
  pfrg_builder_.prepare(scene_);
  impl_ = std::make_unique<Impl>(library, params_, params.threads);
  impl_->cell_owner.assign(max_cells, -1);
  impl_->coarse.reserve(max_cells);
  impl_->fine.reserve(max_cells);
  result_.objects.reserve(static_cast<std::size_t>(std::max(params.max_objects, 1)));
  for (std::size_t i = 0; i < result_.objects.capacity(); ++i) {
    result_.objects.emplace_back();
    result_.objects.back().matches.reserve(64);
    result_.objects.back().path.reserve(64);
    result_.objects.back().inlier_cells.reserve(4096);
  }
  result_.objects.clear();
  result_.note.reserve(256);
}

Recognizer::~Recognizer() = default;

const Recognition& Recognizer::recognize(const OrganizedCloud& cloud, const Plane* table) {
  Impl& im = *impl_;
  const auto t_start = Clock::now();
  Recognition& out = result_;
  // Keep the reserved Hypothesis buffers of out.objects: shrink by resize (no deallocation).
  out.objects.resize(0);
  out.stats = RecognizeStats{};
  out.note.clear();

  // 1. Segmentation and scene PFRG.
  auto t0 = Clock::now();
  segmenter_.segment(cloud, seg_);
  out.stats.segment_ms = ms_since(t0);
  t0 = Clock::now();
  pfrg_builder_.build(seg_, scene_);
  out.stats.regions = static_cast<int>(seg_.regions.size());
  out.stats.known_regions = static_cast<int>(seg_.known_count());
  if (params_.remove_table)
    out.stats.table_removed = remove_table(scene_, table, cloud.viewpoint, params_.table_angle_deg,
                                           params_.table_dist_mm) >= 0;
  out.stats.pfrg_ms = ms_since(t0);
  int known_nodes = 0;
  for (const auto& n : scene_.nodes) known_nodes += n.supernode ? 0 : 1;
  out.stats.scene_nodes = known_nodes;
  out.stats.scene_arcs = static_cast<int>(scene_.arcs.size());
  out.stats.references = static_cast<int>(library_.models.size());
  if (known_nodes == 0) {
    out.note = "no planar face found in the scene (besides the table)";
    out.stats.total_ms = ms_since(t_start);
    return out;
  }

  // 2. Match the scene against every reference (in parallel, one matcher per worker).
  t0 = Clock::now();
  im.scene = &scene_;
  im.library = &library_;
  im.mparams = params_.match;
  im.mparams.max_states = std::min<std::int64_t>(params_.match.max_states, params_.max_states);
  im.mparams.th_minlevel = params_.min_level;
  im.pool.run(library_.models.size(),
              [](void* ctx, std::size_t task, int worker) {
                auto& m = *static_cast<Impl*>(ctx);
                const Model& model = m.library->models[task];
                ModelSlots& ms = m.per_model[task];
                const match::MatchResult& r = m.matchers[static_cast<std::size_t>(worker)]->match(
                    *m.scene, model.graph, m.mparams);
                ms.states = r.stats.states_created;
                ms.count = 0;
                for (const match::Solution& s : r.solutions) {
                  if (ms.count >= static_cast<int>(ms.slots.size())) break;
                  if (s.partial) continue;
                  SolutionSlot& slot = ms.slots[static_cast<std::size_t>(ms.count++)];
                  slot.path.assign(s.path.begin(), s.path.end());
                  slot.matches.assign(s.matches.begin(), s.matches.end());
                  slot.rotation = s.rotation;
                  slot.cost = s.cost;
                  slot.rotfit = s.rotfit_error;
                  slot.level = s.level;
                  slot.rank = s.rank;
                  slot.degenerate = s.degenerate;
                }
              },
              &im);
  out.stats.match_ms = ms_since(t0);

  // 3. Hypotheses: pose, expansion, compatible merge.
  t0 = Clock::now();
  int max_id = 0;
  for (const auto& n : scene_.nodes) max_id = std::max(max_id, n.id);
  im.scene_index.assign(static_cast<std::size_t>(max_id) + 1, -1);
  for (std::size_t i = 0; i < scene_.nodes.size(); ++i) im.scene_index[static_cast<std::size_t>(scene_.nodes[i].id)] = static_cast<int>(i);
  im.nhyp = 0;
  for (std::size_t mi = 0; mi < library_.models.size(); ++mi) {
    const ModelSlots& ms = im.per_model[mi];
    out.stats.states += ms.states;
    for (int k = 0; k < ms.count; ++k) {
      const SolutionSlot& s = ms.slots[static_cast<std::size_t>(k)];
      Hypothesis& h = im.hyps[im.nhyp++];
      h.model = static_cast<int>(mi);
      h.rank = s.rank;
      h.path.assign(s.path.begin(), s.path.end());
      h.matches.clear();
      for (const auto& m : s.matches) h.matches.push_back(FaceMatch{m.scene, m.ref, false});
      h.level = s.level;
      h.R = s.rotation;
      h.cost = s.cost;
      h.rotfit_error = s.rotfit;
      h.degenerate = s.degenerate;
      h.merged = false;
      h.instance = 0;
      h.verify = VerifyResult{};
      h.inlier_cells.clear();
    }
  }
  out.stats.hypotheses = static_cast<int>(im.nhyp);
  HypothesisContext hc{library_, scene_, im.scene_index, cloud.viewpoint, params_};
  for (std::size_t i = 0; i < im.nhyp; ++i) {
    Hypothesis& h = im.hyps[i];
    update_translation(hc, h, im.pairs);
    out.stats.expanded_faces += expand(hc, h, im.pairs);
  }
  im.alive.assign(im.nhyp, 1);
  out.stats.merged = merge_compatible(hc, std::span<Hypothesis>(im.hyps.data(), im.nhyp), im.alive, im.pairs);

  // 4. Low-level verification of the best hypotheses (by matching cost), in parallel.
  im.order.clear();
  for (std::size_t i = 0; i < im.nhyp; ++i)
    if (im.alive[i]) im.order.push_back(i);
  std::sort(im.order.begin(), im.order.end(), [&](std::size_t a, std::size_t b) {
    return im.hyps[a].cost != im.hyps[b].cost ? im.hyps[a].cost < im.hyps[b].cost : a < b;
  });
  if (im.order.size() > static_cast<std::size_t>(params_.max_verified))
    im.order.resize(static_cast<std::size_t>(params_.max_verified));
  // Phase 1: coarse check of every candidate (no refinement).
  im.coarse.build(cloud, 2 * params_.verify.sample_step);
  im.fine.build(cloud, params_.verify.sample_step);
  im.labels = &seg_.labels;
  auto count_regions = [&](const SampleSet& set, std::vector<std::uint32_t>& counts) {
    counts.assign(seg_.regions.size(), 0);
    for (std::uint32_t cell : set.cells()) {
      const std::int32_t r = cell < seg_.labels.size() ? seg_.labels[cell] : -1;
      if (r >= 0 && static_cast<std::size_t>(r) < counts.size()) ++counts[static_cast<std::size_t>(r)];
    }
  };
  count_regions(im.coarse, im.region_coarse);
  count_regions(im.fine, im.region_fine);
  auto verify_task = [](void* ctx, std::size_t task, int worker) {
    auto& m = *static_cast<Impl*>(ctx);
    Hypothesis& h = m.hyps[m.order[task]];
    Verifier& v = m.verifiers[static_cast<std::size_t>(worker)];
    h.verify = v.verify(m.refine_phase ? m.fine : m.coarse, m.geometry[static_cast<std::size_t>(h.model)], h.R,
                        h.t, m.refine_phase);
    h.inlier_cells.assign(v.inlier_cells().begin(), v.inlier_cells().end());
    // How much of the matched scene regions the model explains: a model smaller than the faces it claims
    // leaves measured points of those faces unexplained.
    const auto& counts = m.refine_phase ? m.region_fine : m.region_coarse;
    std::uint64_t total = 0, explained = 0;
    for (const FaceMatch& fm : h.matches) {
      const int r = fm.scene - 1;
      if (r >= 0 && static_cast<std::size_t>(r) < counts.size()) total += counts[static_cast<std::size_t>(r)];
    }
    for (std::uint32_t cell : h.inlier_cells) {
      const std::int32_t r = (*m.labels)[cell];
      for (const FaceMatch& fm : h.matches)
        if (fm.scene - 1 == r) {
          ++explained;
          break;
        }
    }
    h.verify.explained = total > 0 ? std::min(1.0, static_cast<double>(explained) / static_cast<double>(total)) : 0.0;
    h.verify.confidence *= h.verify.explained;
  };
  im.refine_phase = false;
  im.pool.run(im.order.size(), verify_task, &im);
  auto rekey = [&] {
    for (std::size_t i : im.order) {
      Hypothesis& h = im.hyps[i];
      h.key = h.cost + params_.confidence_weight * (1.0 - h.verify.confidence);
    }
    std::stable_sort(im.order.begin(), im.order.end(),
                     [&](std::size_t a, std::size_t b) { return im.hyps[a].key < im.hyps[b].key; });
  };
  rekey();
  // Phase 2: the plausible ones are refined by ICP and verified on the fine sample set.
  std::size_t plausible = 0;
  while (plausible < im.order.size() && plausible < static_cast<std::size_t>(params_.max_refined) &&
         im.hyps[im.order[plausible]].verify.confidence >= 0.5 * params_.min_confidence)
    ++plausible;
  im.refine_phase = true;
  im.pool.run(plausible, verify_task, &im);
  im.order.resize(plausible);
  rekey();
  for (std::size_t i : im.order) {
    Hypothesis& h = im.hyps[i];
    h.faces_visible = count_visible_faces(library_.models[static_cast<std::size_t>(h.model)], h.R, h.t,
                                          cloud.viewpoint);
  }
  out.stats.verify_ms = ms_since(t0);

  // 5. Recognition (ch. 9.4): greedy extraction of the compatible set that holds the best solution.
  im.node_used.assign(static_cast<std::size_t>(max_id) + 1, 0);
  if (im.cell_owner.size() < cloud.points.size()) im.cell_owner.resize(cloud.points.size(), -1);
  im.accepted.clear();
  out.stats.incompatible_pairs = count_incompatible_pairs(std::span<const Hypothesis>(im.hyps.data(), im.nhyp), im.order);
  double best_rejected = -1.0;
  int best_rejected_model = -1;
  for (std::size_t i : im.order) {
    Hypothesis& h = im.hyps[i];
    if (h.verify.confidence < params_.min_confidence) {
      ++out.stats.rejected;
      if (h.verify.confidence > best_rejected) {
        best_rejected = h.verify.confidence;
        best_rejected_model = h.model;
      }
      continue;
    }
    bool clash = false;
    for (const FaceMatch& m : h.matches)
      if (im.node_used[static_cast<std::size_t>(m.scene)]) clash = true;
    if (!clash && !h.inlier_cells.empty()) {
      std::size_t shared = 0;
      for (std::uint32_t c : h.inlier_cells) shared += im.cell_owner[c] >= 0 ? 1 : 0;
      clash = static_cast<double>(shared) > params_.max_shared_inliers * static_cast<double>(h.inlier_cells.size());
    }
    if (clash) continue;
    if (static_cast<int>(out.objects.size()) >= params_.max_objects) break;
    for (const FaceMatch& m : h.matches) im.node_used[static_cast<std::size_t>(m.scene)] = 1;
    const auto obj_index = static_cast<std::int32_t>(out.objects.size());
    for (std::uint32_t c : h.inlier_cells) im.cell_owner[c] = obj_index;
    int instance = 0;
    for (const Hypothesis& o : out.objects) instance += o.model == h.model ? 1 : 0;
    h.instance = instance;
    canonical_pose(library_.models[static_cast<std::size_t>(h.model)], h.R, h.t);
    out.objects.emplace_back();
    copy_hypothesis(h, out.objects.back());
  }
  // Reset the cell owners touched.
  for (const Hypothesis& o : out.objects)
    for (std::uint32_t c : o.inlier_cells) im.cell_owner[c] = -1;
  if (out.objects.empty()) {
    if (im.nhyp == 0) {
      out.note = "no reference matched the scene graph";
    } else if (best_rejected_model >= 0) {
      out.note = "no hypothesis passed verification (best: " +
                 library_.models[static_cast<std::size_t>(best_rejected_model)].name + " with confidence " +
                 std::to_string(best_rejected).substr(0, 5) + " < " + std::to_string(params_.min_confidence).substr(0, 4) + ")";
    } else {
      out.note = "all hypotheses were incompatible";
    }
  }
  out.stats.total_ms = ms_since(t_start);
  return out;
}

std::vector<const Hypothesis*> Recognizer::candidates() const {
  std::vector<const Hypothesis*> out;
  for (std::size_t i : impl_->order) out.push_back(&impl_->hyps[i]);
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
