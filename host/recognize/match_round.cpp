// Recognizer step 2b (thesis ch. 7): every reference PFRG matched against every part of the scene graph, in
// parallel (one InexactMatcher per worker), a batch of references at a time; each batch's solutions become
// hypotheses, at most RecognizeParams::max_hypotheses of them (each model's best ones per part, see
// collect_batch).
#include <algorithm>
#include <limits>

#include "host/match/node_set.hpp"
#include "host/recognize/recognizer_impl.hpp"

namespace fs::host::rec {

using detail::Clock;
using detail::ModelSlots;
using detail::ms_since;
using detail::SolutionSlot;

namespace {

// Whether solution s of `model` in scene part `part` can be one placement (RecognizeParams::placement).
bool placeable(const Pfrg& part, const Model& model, const match::Solution& s, const PlacementCheck& check,
               std::vector<PlanePair>& pairs) {
  pairs.clear();
  for (const match::NodeMatch& nm : s.matches) {
    const PfrgNode* node = part.find(nm.scene);
    if (node && node->has_plane) pairs.push_back(plane_pair(*node, nm.ref));
  }
  return consistent_placement(model, s.rotation, pairs, check);
}

void take_one(ModelSlots& ms, const match::Solution& s, int part_rank) {
  SolutionSlot& slot = ms.slots[static_cast<std::size_t>(ms.count++)];
  slot.part_rank = part_rank;
  slot.path.assign(s.path.begin(), s.path.end());
  slot.matches.assign(s.matches.begin(), s.matches.end());
  slot.rotation = s.rotation;
  slot.cost = s.cost;
  slot.rotfit = s.rotfit_error;
  slot.level = s.level;
  slot.rank = s.rank;
  slot.degenerate = s.degenerate;
}

// Copies r's solutions into ms, at most `room` of them, with part ranks 0, 1, ...: with the placement check
// on, those that pass it first, then the others (`later`, their indices), each group in the matcher's order.
// Among polycubes a search finds a dozen correspondences of equal cost, most of them a cube off, and the
// model's share of the pool holds only a few. (Ranking each group by its prescore as well was tried:
// bench_library_scale, 1,230 polycubes, 83 % top-1 against 88 %.)
void take_solutions(ModelSlots& ms, const match::MatchResult& r, int room, const Pfrg& part,
                    const Model& model, const PlacementCheck& check, std::vector<PlanePair>& pairs,
                    std::vector<int>& later) {
  const bool checked = check.rms_mm > 0;
  int taken = 0;
  later.clear();
  auto full = [&] { return ms.count >= static_cast<int>(ms.slots.size()) || taken >= room; };
  for (std::size_t k = 0; k < r.solutions.size() && !full(); ++k) {
    const match::Solution& s = r.solutions[k];
    if (s.partial) continue;
    if (checked && !placeable(part, model, s, check, pairs))
      later.push_back(static_cast<int>(k));
    else
      take_one(ms, s, taken++);
  }
  for (std::size_t k = 0; k < later.size() && !full(); ++k)
    take_one(ms, r.solutions[static_cast<std::size_t>(later[k])], taken++);
}

// The faces of scene graph g (node indices) that the object of solution s holds: its matched faces and, grown
// through g's adjacency, the real faces whose normal is a face normal of the model in the solution's rotation
// (within 5 degrees).
match::NodeSet object_region(const match::CompactGraph& g, const match::Solution& s, const Model& model) {
  match::NodeSet region;
  for (const match::NodeMatch& nm : s.matches)
    if (const int i = g.index_of(nm.scene); i >= 0) region.set(i);
  constexpr double kCos = 0.99619;  // cos 5 deg
  match::NodeSet tried = region;
  for (;;) {
    match::NodeSet around;
    region.for_each([&](int i) { around = around | g.adj[static_cast<std::size_t>(i)]; });
    const match::NodeSet fresh = (around & g.real).minus(tried);
    if (!fresh.any()) break;
    tried = tried | fresh;
    fresh.for_each([&](int i) {
      const Vec3& normal = g.normal[static_cast<std::size_t>(i)];
      for (const ModelFace& f : model.faces)
        if ((s.rotation * f.normal).dot(normal) > kCos) {
          region.set(i);
          break;
        }
    });
  }
  return region;
}

// Worker task: model batch_first + task against every part.
void match_model(void* ctx, std::size_t task, int worker) {
  auto& m = *static_cast<Recognizer::Impl*>(ctx);
  const Model& model = m.library->models[m.batch_first + task];
  ModelSlots& ms = m.batch[task];
  ms.states = 0;
  ms.count = 0;
  // A model of more faces than the matcher takes (kept by `library build --allow-large`) is never matched.
  if (model.graph.nodes.size() > static_cast<std::size_t>(match::kMaxNodes)) return;
  // Each connected part of the scene graph is searched on its own (a solution is connected, so
  // it lies in one part); the model's solution slots are shared out evenly among the parts (and between
  // the two searches of a part, RecognizeParams::second_search).
  const std::size_t searches = m.second_search ? 2 : 1;
  const int per_part = static_cast<int>((ms.slots.size() / searches + m.nparts - 1) / m.nparts);
  const std::uint64_t mask = m.part_mask[m.batch_first + task];
  match::InexactMatcher& matcher = *m.matchers[static_cast<std::size_t>(worker)];
  std::vector<PlanePair>& pairs = m.worker_pairs[static_cast<std::size_t>(worker)];
  std::vector<int>& later = m.worker_later[static_cast<std::size_t>(worker)];
  match::SearchScope scope = match::full_scope();
  if (!m.search_roots.empty()) scope.first_refs = m.search_roots[m.batch_first + task];
  for (std::size_t part = 0; part < m.nparts; ++part) {
    if (!((mask >> part) & 1u)) continue;  // the arc index: no solution possible
    const bool small = m.round_small || m.part_faces[part] < m.mparams.th_minlevel;
    const match::MatchParams& mp = small ? m.mparams_small : m.mparams;
    scope.scene = ~match::NodeSet{};
    const match::MatchResult& r = matcher.match(m.parts[part], model.graph, mp, scope);
    ms.states += r.stats.states_created;
    take_solutions(ms, r, per_part, m.parts[part], model, m.placement, pairs, later);
    if (!m.second_search || r.stats.stop != match::StopReason::kSolutionsFound) continue;
    // The part without the object of the first solution: searched again when it has faces enough.
    const match::Solution* first = nullptr;
    for (const match::Solution& s : r.solutions)
      if (s.complete) {
        first = &s;
        break;
      }
    if (!first || first->level < m.second_search_min_level) continue;
    const match::CompactGraph& g = matcher.scene_graph();
    const match::NodeSet region = object_region(g, *first, model);
    if (g.real.minus(region).count() < mp.th_minlevel) continue;
    scope.scene = ~region;
    const match::MatchResult& r2 =
        matcher.match(m.parts[part], model.graph, small ? m.mparams_small_second : m.mparams_second, scope);
    ms.states += r2.stats.states_created;
    take_solutions(ms, r2, per_part, m.parts[part], model, m.placement, pairs, later);
  }
}

// Higher matching cost first, then the later model, then the later solution of a model: the top of the heap
// is the hypothesis a better solution replaces when the pool is full.
bool worse(const Hypothesis& a, const Hypothesis& b) {
  if (a.cost != b.cost) return a.cost > b.cost;
  if (a.model != b.model) return a.model > b.model;
  return a.rank > b.rank;
}

void fill(Hypothesis& h, int model, const SolutionSlot& s) {
  h.model = model;
  h.rank = s.rank;
  h.part_rank = s.part_rank;
  h.path.assign(s.path.begin(), s.path.end());
  h.matches.clear();
  for (const auto& m : s.matches) h.matches.push_back(FaceMatch{m.scene, m.ref, false});
  h.level = s.level;
  h.R = s.rotation;
  h.cost = s.cost;
  h.rotfit_error = s.rotfit;
  h.degenerate = s.degenerate;
  h.merged = false;
  h.partial_face = false;
  h.raised = false;
  h.instance = 0;
  h.verify = VerifyResult{};
  h.inlier_cells.clear();
}

}  // namespace

void Recognizer::Impl::match_references(const Library& lib, int round, RecognizeStats& stats) {
  const auto t0 = Clock::now();
  nhyp = 0;
  pool_full = false;
  worst.clear();
  quota = std::numeric_limits<int>::max();
  const std::size_t models = nparts == 0 ? 0 : lib.models.size();
  part_mask.assign(models, use_arc_index ? 0 : ~std::uint64_t{0});
  if (use_arc_index) {
    for (std::size_t part = 0; part < nparts; ++part) {
      const bool small = round_small || part_faces[part] < mparams.th_minlevel;
      arc_index->candidates(parts[part], small ? mparams_small : mparams, part_mask, std::uint64_t{1} << part,
                            arc_scratch);
    }
  }
  for (std::uint64_t m : part_mask) stats.references_searched += m != 0;
  for (batch_first = 0; batch_first < models; batch_first += kMatchBatch) {
    const std::size_t n = std::min(kMatchBatch, models - batch_first);
    pool.run(n, match_model, this);
    collect_batch(n, stats);
  }
  // Replacements leave the pool out of model order; the compatible merge needs each model's run together.
  if (pool_full) {
    std::sort(hyps.begin(), hyps.begin() + static_cast<std::ptrdiff_t>(nhyp),
              [](const Hypothesis& a, const Hypothesis& b) {
                return a.model != b.model ? a.model < b.model : a.rank < b.rank;
              });
  }
  stats.match_ms += ms_since(t0);
  stats.rounds = round + 1;
}

// hyps[0 .. nhyp) without the hypotheses of part_rank >= quota (order kept, buffers swapped, not copied).
std::size_t Recognizer::Impl::trim_to_quota() {
  std::size_t w = 0;
  for (std::size_t i = 0; i < nhyp; ++i) {
    if (hyps[i].part_rank >= quota) continue;
    if (w != i) std::swap(hyps[w], hyps[i]);
    ++w;
  }
  const std::size_t removed = nhyp - w;
  nhyp = w;
  return removed;
}

// The batch's solutions (model order, deterministic whatever the threads did) into hyps. While there is room
// all are kept. When the pool is full, the quota of solutions per model and scene part goes down (each keeps
// its best ones, as the matcher ranked them) until they fit: every model keeps the same number in every part,
// so a model that fits one object is not crowded out by thousands that fit another. At one per model and
// part, a solution replaces the kept one of highest matching cost when it costs less.
void Recognizer::Impl::collect_batch(std::size_t n, RecognizeStats& stats) {
  auto heap_less = [this](std::size_t a, std::size_t b) { return worse(hyps[b], hyps[a]); };
  for (std::size_t k = 0; k < n; ++k) {
    ModelSlots& ms = batch[k];
    stats.states += ms.states;
    stats.solutions += ms.count;
    const int model = static_cast<int>(batch_first + k);
    for (int j = 0; j < ms.count; ++j) {
      const SolutionSlot& s = ms.slots[static_cast<std::size_t>(j)];
      while (nhyp == max_solutions && !pool_full && s.part_rank < quota) {
        int top = s.part_rank;  // the highest rank present goes
        for (std::size_t i = 0; i < nhyp; ++i) top = std::max(top, hyps[i].part_rank);
        if (top == 0) break;
        quota = top;
        stats.solutions_dropped += static_cast<std::int64_t>(trim_to_quota());
      }
      if (s.part_rank >= quota) {
        ++stats.solutions_dropped;
        continue;
      }
      if (nhyp < max_solutions) {
        fill(hyps[nhyp++], model, s);
        continue;
      }
      if (!pool_full) {  // full at one per model and part: heap of all it holds
        pool_full = true;
        for (std::size_t i = 0; i < nhyp; ++i) worst.push_back(i);
        std::make_heap(worst.begin(), worst.end(), heap_less);
      }
      ++stats.solutions_dropped;
      const Hypothesis& top = hyps[worst.front()];
      if (!(s.cost < top.cost)) continue;  // a later model or rank with an equal cost stays out
      std::pop_heap(worst.begin(), worst.end(), heap_less);
      fill(hyps[worst.back()], model, s);
      std::push_heap(worst.begin(), worst.end(), heap_less);
    }
    ms.count = 0;
    ms.states = 0;
  }
}

}  // namespace fs::host::rec
