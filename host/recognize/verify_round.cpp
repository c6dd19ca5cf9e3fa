// Recognizer step 4 (beyond the thesis, its outlook ch. 10): low-level verification of the hypotheses against
// the measured cloud, in parallel: a coarse check of the most plausible ones (prescore, matched scene area,
// then matching cost; every scene face its share), then ICP refinement and the fine check of those that pass
// it.
#include <algorithm>
#include <cstddef>

#include "host/recognize/recognizer_impl.hpp"

namespace fs::host::rec {

using detail::ms_since;

namespace {

// The largest scene node id any hypothesis in order holds.
int max_scene_id_of(const Recognizer::Impl& im) {
  int max_id = 0;
  for (std::size_t i : im.order)
    for (const FaceMatch& m : im.hyps[i].matches) max_id = std::max(max_id, m.scene);
  return max_id;
}

// Filters im.order (kept in order) to at most `limit` hypotheses that pass `ok` and hold a scene face that
// fewer than `per_face` earlier picks hold. One for which `waits(h)` holds (asked with the picks so far in
// im.picked, as positions in im.order) has its turn after the others, and keeps its place in the order: it
// goes before the first other h for which `ends_wait(w, h)` holds, or after all.
template <class Ok, class Waits, class EndsWait>
void select_covering(Recognizer::Impl& im, int per_face, std::size_t limit, Ok ok, Waits waits,
                     EndsWait ends_wait) {
  im.face_cover.assign(static_cast<std::size_t>(max_scene_id_of(im)) + 1, 0);
  im.picked.clear();
  im.waiting.clear();
  bool deferred = false;
  auto take = [&](std::size_t k) {
    const Hypothesis& h = im.hyps[im.order[k]];
    bool wanted = false;
    for (const FaceMatch& m : h.matches)
      wanted = wanted || im.face_cover[static_cast<std::size_t>(m.scene)] < per_face;
    if (!wanted) return;
    for (const FaceMatch& m : h.matches) ++im.face_cover[static_cast<std::size_t>(m.scene)];
    im.picked.push_back(k);
  };
  for (std::size_t k = 0; k < im.order.size() && im.picked.size() < limit; ++k) {
    const Hypothesis& h = im.hyps[im.order[k]];
    if (!ok(h)) continue;
    if (waits(h)) {
      im.waiting.push_back(k);
      deferred = true;
      continue;
    }
    for (std::size_t w = 0; w < im.waiting.size() && im.picked.size() < limit;) {
      if (ends_wait(im.hyps[im.order[im.waiting[w]]], h)) {
        take(im.waiting[w]);
        im.waiting.erase(im.waiting.begin() + static_cast<std::ptrdiff_t>(w));
      } else {
        ++w;
      }
    }
    if (im.picked.size() < limit) take(k);
  }
  for (std::size_t k : im.waiting) {
    if (im.picked.size() >= limit) break;
    take(k);
  }
  if (deferred) std::sort(im.picked.begin(), im.picked.end());
  for (std::size_t& k : im.picked) k = im.order[k];
  im.order.assign(im.picked.begin(), im.picked.end());
}

template <class Ok>
void select_covering(Recognizer::Impl& im, int per_face, std::size_t limit, Ok ok) {
  select_covering(
      im, per_face, limit, ok, [](const Hypothesis&) { return false; },
      [](const Hypothesis&, const Hypothesis&) { return false; });
}

// The refinement's waiting rule (RecognizeParams::refine_models_first): a pick of h's own model already holds
// a scene face h holds. Placements of one model on the same faces differ in the coarse check by how well the
// coarse pose sits (a partly hidden face fixes the translation loosely) or only out of view (near symmetries;
// an augmentation on a hidden side): a look-alike model next in the order, or the true model whose coarse
// pose sits a little worse, would get no place on the face. The wait ends at the first other hypothesis whose
// coarse confidence is lower by more than refine_wait_margin: that one is no rival.
bool holds_a_face_of_a_pick_of_its_model(const Recognizer::Impl& im, const Hypothesis& h) {
  for (std::size_t k : im.picked) {
    const Hypothesis& q = im.hyps[im.order[k]];
    if (q.model != h.model) continue;
    for (const FaceMatch& a : h.matches)
      for (const FaceMatch& b : q.matches)
        if (a.scene == b.scene) return true;
  }
  return false;
}

// Worker task: verifies hypothesis order[task] (coarse, or refined and fine in the refine phase), then
// scales its confidence by the share of its matched scene regions it explains.
void verify_task(void* ctx, std::size_t task, int worker) {
  auto& m = *static_cast<Recognizer::Impl*>(ctx);
  Hypothesis& h = m.hyps[m.order[task]];
  Verifier& v = m.verifiers[static_cast<std::size_t>(worker)];
  const ModelGeometry& g = m.geometry[static_cast<std::size_t>(h.model)];
  h.verify = m.refine_phase && h.free_dims == 1
                 ? v.verify_sliding(m.fine, m.coarse, g, h.R, h.t, h.free_dir)
                 : v.verify(m.refine_phase ? m.fine : m.coarse, g, h.R, h.t, m.refine_phase);
  const std::vector<std::uint32_t>* cells = &v.inlier_cells();
  if (m.refine_phase) {
    m.slot_owner[m.slot_base + task] = m.order[task];
    std::swap(h.inlier_cells, m.slot_cells[m.slot_base + task]);
    h.inlier_cells.assign(v.inlier_cells().begin(), v.inlier_cells().end());
    cells = &h.inlier_cells;
  } else {
    m.raw_confidence[m.order[task]] = h.verify.confidence;
  }
  m.scale_by_explained(h, *cells, m.refine_phase);
  if (m.refine_phase) {
    if (h.free_dims == 1) m.snap_to_table(m.library->models[static_cast<std::size_t>(h.model)], h, v);
    m.support_test(m.library->models[static_cast<std::size_t>(h.model)], h);
  } else {
    m.reseat(m.order[task], worker);
    m.sink_test(m.library->models[static_cast<std::size_t>(h.model)], h);
  }
}

// Ordering key of a checked hypothesis (lower first): cost + weight * (1 - confidence) - inlier_weight *
// inliers / the most inliers among those ordered.
double ordering_key(const RecognizeParams& params, double cost, double confidence, int inliers,
                    int most_inliers) {
  return cost + params.confidence_weight * (1.0 - confidence) -
         params.inlier_weight * static_cast<double>(inliers) / static_cast<double>(most_inliers);
}

// The order of verification before any check: prescore, then matched scene area, then cost (a, b: the
// hypotheses' indices, the last tie-break).
bool prescore_before(const Hypothesis& x, const Hypothesis& y, std::size_t a, std::size_t b) {
  if (x.prescore != y.prescore) return x.prescore > y.prescore;
  if (x.matched_area != y.matched_area) return x.matched_area > y.matched_area;
  return x.cost != y.cost ? x.cost < y.cost : a < b;
}

// Sorts im.order by the ordering key; ties (look-alikes that fit alike) keep the prescore order (std::sort
// with that as its last key: std::stable_sort would take a temporary buffer from the heap).
void sort_by_key(Recognizer::Impl& im) {
  std::sort(im.order.begin(), im.order.end(), [&](std::size_t a, std::size_t b) {
    const Hypothesis& x = im.hyps[a];
    const Hypothesis& y = im.hyps[b];
    if (x.key != y.key) return x.key < y.key;
    return prescore_before(x, y, a, b);
  });
}

// Worker task of the screening: hypothesis order[task] on the sparse samples, scaled by the share of its
// matched scene regions it explains (h.verify is left as it was).
void screen_task(void* ctx, std::size_t task, int worker) {
  auto& m = *static_cast<Recognizer::Impl*>(ctx);
  Hypothesis& h = m.hyps[m.order[task]];
  Verifier& v = m.verifiers[static_cast<std::size_t>(worker)];
  const ModelGeometry& g = m.geometry[static_cast<std::size_t>(h.model)];
  const VerifyResult r = v.verify(m.screen, g, h.R, h.t, false);
  h.screened = r.confidence * m.explained_share(h, v.inlier_cells(), m.region_screen);
  h.screened_inliers = r.inliers;
}

}  // namespace

double Recognizer::Impl::explained_share(const Hypothesis& h, const std::vector<std::uint32_t>& cells,
                                         const std::vector<std::uint32_t>& counts) const {
  std::uint64_t total = 0, explained = 0;
  for (const FaceMatch& fm : h.matches) {
    const int r = fm.scene - 1;
    if (r >= 0 && static_cast<std::size_t>(r) < counts.size()) total += counts[static_cast<std::size_t>(r)];
  }
  for (std::uint32_t cell : cells) {
    const std::int32_t r = (*labels)[cell];
    for (const FaceMatch& fm : h.matches)
      if (fm.scene - 1 == r) {
        ++explained;
        break;
      }
  }
  return total > 0 ? std::min(1.0, static_cast<double>(explained) / static_cast<double>(total)) : 0.0;
}

// When there are more hypotheses than max_verified: the first max_screened in prescore order (screen_per_face
// per scene face) are checked on the sparse samples and go first, best screened first (by the coarse check's
// ordering key); the unscreened rest follows in prescore order, so a scene face the screening budget did not
// reach still gets its share of the checks.
void Recognizer::Impl::screen_hypotheses(const RecognizeParams& params) {
  if (params.max_screened <= 0 || order.size() <= static_cast<std::size_t>(params.max_verified)) return;
  order_copy.assign(order.begin(), order.end());
  select_covering(*this, params.screen_per_face, static_cast<std::size_t>(params.max_screened),
                  [](const Hypothesis&) { return true; });
  if (order.size() <= static_cast<std::size_t>(params.max_verified)) {
    order.assign(order_copy.begin(), order_copy.end());
    return;
  }
  pool.run(order.size(), screen_task, this);
  // The coarse check's ordering key (rekey) on the screening's values; ties keep the prescore order.
  int most_inliers = 1;
  for (std::size_t i : order) most_inliers = std::max(most_inliers, hyps[i].screened_inliers);
  for (std::size_t i : order)
    hyps[i].key =
        ordering_key(params, hyps[i].cost, hyps[i].screened, hyps[i].screened_inliers, most_inliers);
  sort_by_key(*this);
  for (std::size_t i : order_copy)
    if (hyps[i].screened < 0.0) order.push_back(i);
}

// How much of the matched scene regions the model explains (cells: its inlier cells): a model smaller than
// the faces it claims leaves measured points of those faces unexplained.
void Recognizer::Impl::scale_by_explained(Hypothesis& h, const std::vector<std::uint32_t>& cells,
                                          bool fine_samples) const {
  h.verify.explained = explained_share(h, cells, fine_samples ? region_fine : region_coarse);
  h.verify.confidence *= h.verify.explained;
}

void Recognizer::Impl::verify_hypotheses(Recognizer& rz, const HypothesisContext& hc,
                                         const OrganizedCloud& cloud, RecognizeStats& stats) {
  const RecognizeParams& params = rz.params_;
  order.clear();
  for (std::size_t i = 0; i < nhyp; ++i)
    if (alive[i]) order.push_back(i);
  for (std::size_t i : order) {
    hyps[i].prescore = prescore(hc, hyps[i]);
    hyps[i].matched_area = matched_scene_area(hc, hyps[i]);
  }
  reseated.assign(nhyp, 0);
  raw_confidence.assign(nhyp, 0.0);
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return prescore_before(hyps[a], hyps[b], a, b); });
  for (std::size_t i : order) hyps[i].screened = -1.0;
  screen_hypotheses(params);
  // Keep the order but give every scene face its share: a hypothesis is checked when one of its matched
  // scene faces has been claimed by fewer than verify_per_face better hypotheses (so the faces of a small
  // object are not crowded out by the many hypotheses of a large one). The shares ration a budget that is
  // short: when all fit in it, all are checked (check_all_that_fit).
  if (!params.check_all_that_fit || order.size() > static_cast<std::size_t>(params.max_verified))
    select_covering(*this, params.verify_per_face, static_cast<std::size_t>(params.max_verified),
                    [](const Hypothesis&) { return true; });
  // Phase 1: coarse check of every candidate (no refinement); then a hypothesis of a near-symmetric model
  // moves to its best placement (reseat.cpp).
  refine_phase = false;
  hctx = &hc;
  reseat_min_confidence = 0.5 * params.min_confidence;
  pool.run(order.size(), verify_task, this);
  for (std::size_t i : order) stats.reseated += reseated[i];
  drop_reseated_duplicates(params);
  rekey(params);
  // Phase 2: the plausible ones are refined by ICP and verified on the fine sample set.
  const double min_plausible = 0.5 * params.min_confidence;
  coarse_order.assign(order.begin(), order.end());
  face_best.assign(static_cast<std::size_t>(max_scene_id_of(*this)) + 1, 0.0);
  for (std::size_t i : coarse_order)
    for (const FaceMatch& m : hyps[i].matches)
      face_best[static_cast<std::size_t>(m.scene)] =
          std::max(face_best[static_cast<std::size_t>(m.scene)], hyps[i].verify.confidence);
  select_covering(
      *this, params.refine_per_face, static_cast<std::size_t>(params.max_refined),
      [&](const Hypothesis& h) { return h.verify.confidence >= min_plausible; },
      [&](const Hypothesis& h) {
        return params.refine_models_first && holds_a_face_of_a_pick_of_its_model(*this, h);
      },
      [&](const Hypothesis& w, const Hypothesis& h) {
        return h.verify.confidence < w.verify.confidence - params.refine_wait_margin;
      });
  std::size_t plausible = order.size();
  refine_phase = true;
  slot_base = 0;
  slot_owner.resize(std::min(plausible, slot_cells.size()));
  plausible = slot_owner.size();
  pool.run(plausible, verify_task, this);
  order.resize(plausible);
  refine_again(params, min_plausible);
  rekey(params);
  for (std::size_t i : order) {
    Hypothesis& h = hyps[i];
    h.faces_visible =
        count_visible_faces(rz.library_.models[static_cast<std::size_t>(h.model)], h.R, h.t, cloud.viewpoint);
  }
  stats.verify_ms += ms_since(hyp_t0);
}

// A scene face whose refined hypotheses all failed the fine check (confidence < min_confidence) gets the next
// plausible ones of the coarse order that hold it and tie with its best coarse confidence (within
// refine_again_margin), refine_per_face of them, in the slots left: look-alikes that tie on the coarse
// samples (polycubes) are told apart only by the fine check, and the true one may come fourth.
void Recognizer::Impl::refine_again(const RecognizeParams& params, double min_plausible) {
  const std::size_t used = order.size();
  // slot_cells holds at least one slot; max_refined bounds both passes together.
  const std::size_t slots =
      std::min(slot_cells.size(), static_cast<std::size_t>(std::max(params.max_refined, 0)));
  if (params.refine_again_margin < 0.0 || used >= slots) return;
  // face_cover (sized by select_covering for every scene face of the coarse-checked hypotheses): -1 = the
  // face has a passing refined hypothesis, else the count of the second pass.
  std::fill(face_cover.begin(), face_cover.end(), 0);
  refined.assign(nhyp, 0);
  for (std::size_t i : order) {
    refined[i] = 1;
    if (hyps[i].verify.confidence >= detail::pass_confidence(hyps[i], params))
      for (const FaceMatch& m : hyps[i].matches) face_cover[static_cast<std::size_t>(m.scene)] = -1;
  }
  picked.clear();
  for (std::size_t i : coarse_order) {
    if (picked.size() >= slots - used) break;
    const Hypothesis& h = hyps[i];
    if (refined[i] || h.verify.confidence < min_plausible) continue;
    bool wanted = false;
    for (const FaceMatch& m : h.matches) {
      const auto f = static_cast<std::size_t>(m.scene);
      wanted = wanted || (face_cover[f] >= 0 && face_cover[f] < params.refine_per_face &&
                          h.verify.confidence >= face_best[f] - params.refine_again_margin);
    }
    if (!wanted) continue;
    for (const FaceMatch& m : h.matches)
      if (face_cover[static_cast<std::size_t>(m.scene)] >= 0) ++face_cover[static_cast<std::size_t>(m.scene)];
    picked.push_back(i);
  }
  if (picked.empty()) return;
  order_copy.assign(order.begin(), order.end());  // the first pass
  order.assign(picked.begin(), picked.end());
  slot_base = used;
  slot_owner.resize(used + picked.size());
  pool.run(picked.size(), verify_task, this);
  slot_base = 0;
  order.assign(order_copy.begin(), order_copy.end());
  order.insert(order.end(), picked.begin(), picked.end());
}

// Ordering key of the verified hypotheses (order sorted by it).
void Recognizer::Impl::rekey(const RecognizeParams& params) {
  // Of two hypotheses that fit equally, the one explaining more measured points goes first: a model that
  // covers only part of an object (a prism for the augmented prism) leaves the rest unexplained.
  int most_inliers = 1;
  for (std::size_t i : order) most_inliers = std::max(most_inliers, hyps[i].verify.inliers);
  for (std::size_t i : order)
    hyps[i].key =
        ordering_key(params, hyps[i].cost, hyps[i].verify.confidence, hyps[i].verify.inliers, most_inliers);
  sort_by_key(*this);
}

// The coarse check's part of the support test (vertices only, no search of the measured points): a model
// that sinks into the table is not a physical placement, though the table points its hidden part lies under
// count as its inliers (a look-alike larger than the object, its extra part under the table).
void Recognizer::Impl::sink_test(const Model& model, Hypothesis& h) const {
  if (have_table && lowest_point(model, h.R, h.t, table) < -support_tol)
    h.verify.confidence *= unsupported_factor;
}

void Recognizer::Impl::snap_to_table(const Model& model, Hypothesis& h, Verifier& v) const {
  if (!have_table || table_snap <= 0.0 || h.free_dir.squaredNorm() < 0.25) return;
  const Vec3 u = h.free_dir.normalized();
  const double climb = u.dot(table.n);  // height gained per mm along u
  if (std::abs(climb) < 0.1) return;    // (nearly) level: the table does not place it along u
  const double low = lowest_point(model, h.R, h.t, table);
  if (std::abs(low) <= support_tol || std::abs(low) > table_snap) return;
  Mat3 R = h.R;
  Vec3 t = h.t - (low / climb) * u;
  VerifyResult e = v.verify(fine, geometry[static_cast<std::size_t>(h.model)], R, t, false);
  // On the table it must not be seen through more (the true pose is not), nor explain much less.
  if (e.inliers < v.params().slide_keep_inliers * h.verify.inliers ||
      e.violations > h.verify.violations + std::max(2, h.verify.inliers / 100))
    return;
  e.explained = explained_share(h, v.inlier_cells(), region_fine);
  e.confidence *= e.explained;
  if (e.confidence < h.verify.confidence - table_snap_slack) return;
  // The move is parallel to the matched planes: their inliers' plane distances (the rms) stay.
  e.refine_iterations = h.verify.refine_iterations;
  e.rms_mm = h.verify.rms_mm;
  h.t = t;
  h.verify = e;
  h.inlier_cells.assign(v.inlier_cells().begin(), v.inlier_cells().end());
}

SupportParams Recognizer::Impl::support_params(const Hypothesis& h, double fit) const {
  // Space hidden under a solid holds it up only when the solid itself is seen clearly: its pose fixed by
  // enough matched faces, its fit high. A raised top rests on what it hides by its premise: it may use it
  // with its one face (it is accepted only at single_face_hidden_min_confidence).
  const bool look = support_hidden_below &&
                    (static_cast<int>(h.matches.size()) >= hidden_below_min_faces || h.raised) &&
                    fit >= hidden_below_min_fit;
  return SupportParams{support_tol,      support_radius,        unsupported_factor, look,
                       fine.viewpoint(), hidden_below_min_rays, support_own_plane};
}

void Recognizer::Impl::support_test(const Model& model, Hypothesis& h) const {
  if (!have_table) return;
  h.verify.support = support_factor(model, h.R, h.t, table, MeasuredPoints(fine),
                                    support_params(h, h.verify.confidence), &h.verify.lowest_mm);
  h.verify.confidence *= h.verify.support;
}

}  // namespace fs::host::rec
