// Recognizer step 5 (thesis ch. 9.4): recognition, the extraction of a compatible set from the best verified
// hypothesis down (no shared scene face, few shared inliers, no interpenetrating solids; a reused model is a
// second instance; an object is supported by the table, by measured points under it or by an accepted
// object). Beyond the thesis's greedy extraction, a hypothesis that explains the points of the objects it
// conflicts with, and more, or fits the same points better, replaces them; a look-alike met only across
// rounds is listed as an alternative; and the report of an empty result.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

#include "host/recognize/recognizer_impl.hpp"
#include "host/recognize/support.hpp"

namespace fs::host::rec {

namespace {

// Lists model `model` (confidence `fit`, `inliers` inlier points) as an alternative of accepted object o when
// it fits o's points as well (confidence within alternative_confidence, inliers >= alternative_inliers x
// o's less alternative_inlier_slack), is another model, is not listed yet and there is room: a look-alike
// that met o across rounds. (R, t): its pose. `compared` and `object_compared`, when given, are the fits
// compared instead of the confidences (seen_fit).
void list_alternative(const RecognizeParams& params, const Library& library, int model, double fit,
                      int inliers, const Mat3& R, const Vec3& t, Hypothesis& o, double compared = -1.0,
                      double object_compared = -1.0) {
  if (compared < 0.0) compared = fit, object_compared = o.verify.confidence;
  if (model == o.model || o.alternatives >= Hypothesis::kMaxAlternatives ||
      compared < object_compared - params.alternative_confidence ||
      static_cast<double>(inliers + params.alternative_inlier_slack) <
          params.alternative_inliers * static_cast<double>(o.verify.inliers))
    return;
  for (const Hypothesis::Alternative& a : o.listed_alternatives())
    if (a.model == model) return;
  Hypothesis::Alternative& a = o.alternative[static_cast<std::size_t>(o.alternatives++)];
  a = {model, fit, R, t};
  canonical_pose(library.models[static_cast<std::size_t>(model)], a.R, a.t);
}

// A verified hypothesis's fit without its occluded rays: what the measured points in view say of it (scaled
// as its confidence is: the explained share, the support factor, and fewer inliers than min_inliers).
double seen_fit(const VerifyResult& v, int min_inliers) {
  const double seen = static_cast<double>(v.inliers + v.violations);
  if (seen <= 0.0) return 0.0;
  double f = static_cast<double>(v.inliers) / seen * v.explained * v.support;
  if (v.inliers < min_inliers) f *= static_cast<double>(v.inliers) / static_cast<double>(min_inliers);
  return f;
}

// The refined hypotheses of other models that explain the accepted hypothesis h (index `self`) as well: on at
// least half of its scene faces, fit within alternative_confidence (seen_fit with alternative_seen_fit),
// inliers >= alternative_inliers x its own less the slack.
void find_alternatives(const Recognizer::Impl& im, std::size_t self, const RecognizeParams& params,
                       Hypothesis& h) {
  h.alternatives = 0;
  for (std::size_t j : im.order) {
    if (h.alternatives >= Hypothesis::kMaxAlternatives) break;
    const Hypothesis& o = im.hyps[j];
    if (j == self || (o.partial_face && o.verify.confidence < detail::pass_confidence(o, params))) continue;
    std::size_t shared = 0;
    for (const FaceMatch& m : h.matches)
      for (const FaceMatch& om : o.matches) shared += om.scene == m.scene ? 1 : 0;
    if (2 * shared < h.matches.size()) continue;
    if (params.alternative_seen_fit)
      list_alternative(params, *im.library, o.model, o.verify.confidence, o.verify.inliers, o.R, o.t, h,
                       seen_fit(o.verify, params.verify.min_inliers),
                       seen_fit(h.verify, params.verify.min_inliers));
    else
      list_alternative(params, *im.library, o.model, o.verify.confidence, o.verify.inliers, o.R, o.t, h);
  }
}

}  // namespace

void Recognizer::Impl::remove_object(Recognition& out, std::size_t k) {
  for (std::uint32_t c : out.objects[k].inlier_cells)
    if (cell_owner[c] == static_cast<std::int32_t>(k)) cell_owner[c] = -1;
  for (const FaceMatch& m : out.objects[k].matches) node_used[static_cast<std::size_t>(m.scene)] = 0;
  for (std::size_t j = k + 1; j < out.objects.size(); ++j)
    for (std::uint32_t c : out.objects[j].inlier_cells)
      if (cell_owner[c] == static_cast<std::int32_t>(j)) cell_owner[c] = static_cast<std::int32_t>(j - 1);
  // The removed object's buffers go back to the spare pool (see spare_objects): no buffer is freed.
  std::rotate(out.objects.begin() + static_cast<std::ptrdiff_t>(k),
              out.objects.begin() + static_cast<std::ptrdiff_t>(k) + 1, out.objects.end());
  std::swap(out.objects.back(), spare_objects[out.objects.size() - 1]);
  out.objects.pop_back();
}

// What h shares with each accepted object: scene faces, inlier cells, interpenetration depth.
void Recognizer::Impl::measure_conflicts(const Hypothesis& h, const Recognition& out) {
  const std::size_t n = out.objects.size();
  conflict_cells.assign(n, 0);
  conflict_faces.assign(n, 0);
  conflict_depth.assign(n, 0.0);
  conflict_share.assign(n, 0.0);
  for (std::uint32_t c : h.inlier_cells)
    if (cell_owner[c] >= 0) ++conflict_cells[static_cast<std::size_t>(cell_owner[c])];
  const ModelGeometry& gh = geometry[static_cast<std::size_t>(h.model)];
  for (std::size_t k = 0; k < n; ++k) {
    const Hypothesis& o = out.objects[k];
    for (const FaceMatch& m : h.matches)
      for (const FaceMatch& om : o.matches) conflict_faces[k] += om.scene == m.scene ? 1 : 0;
    const Interpenetration ip =
        interpenetration(gh, h.R, h.t, geometry[static_cast<std::size_t>(o.model)], o.R, o.t);
    conflict_share[k] = ip.volume_share;
    conflict_depth[k] = ip.depth_mm;
  }
}

// h, unsupported by the table or by measured points under it, rests on an accepted object: its confidence
// is restored (the support test's factor undone).
bool Recognizer::Impl::supported_by_accepted(Hypothesis& h, const Recognition& out) const {
  if (h.verify.support >= 1.0 || h.verify.support <= 0.0) return false;
  if (!have_table) return false;
  const PosedModel upper{&geometry[static_cast<std::size_t>(h.model)], h.R, h.t};
  for (const Hypothesis& o : out.objects)
    if (rests_on(upper, h.verify.lowest_mm, {&geometry[static_cast<std::size_t>(o.model)], o.R, o.t}, table,
                 support_tol)) {
      h.verify.confidence /= h.verify.support;
      h.verify.support = 1.0;
      return true;
    }
  return false;
}

// Accepts hyps[i] unless it conflicts with the accepted objects and cannot replace them; false when it is
// not accepted.
bool Recognizer::Impl::accept_one(const RecognizeParams& params, Recognizer& rz, std::size_t i,
                                  Recognition& out) {
  Hypothesis& h = hyps[i];
  // Conflicts with the accepted objects (thesis ch. 9's incompatibility, and a physically possible world):
  // a shared scene face, too many shared inliers, or solids that interpenetrate.
  measure_conflicts(h, out);
  bool clash = false, solid_clash = false;
  std::size_t shared = 0;
  for (std::size_t k = 0; k < out.objects.size(); ++k) {
    shared += static_cast<std::size_t>(conflict_cells[k]);
    clash = clash || conflict_faces[k] > 0;
    solid_clash = solid_clash || interpenetrates(params, k);
  }
  clash =
      clash || solid_clash ||
      static_cast<double>(shared) > params.max_shared_inliers * static_cast<double>(h.inlier_cells.size());
  if (clash) {
    // One model that explains the points of the objects it conflicts with, and more, at least as well
    // replaces them (a larger model over a region that smaller ones split; the points decide).
    // `better`: the other way to replace them, a better fit of the same points (below).
    double replaced_inliers = 0.0;
    int replaced_violations = 0;
    bool replace = true, better = true, net = params.replace_violation_weight > 0.0;
    const double h_fit = seen_fit(h.verify, params.verify.min_inliers);
    int conflicts = 0;
    for (std::size_t k = 0; k < out.objects.size(); ++k) {
      const Hypothesis& o = out.objects[k];
      const double own = static_cast<double>(o.inlier_cells.size());
      if (!conflicts_with(params, k, out)) continue;
      ++conflicts;
      const bool covers = static_cast<double>(conflict_cells[k]) >= params.replace_cover * own;
      replace =
          replace && covers && h.verify.confidence >= o.verify.confidence - params.alternative_confidence;
      better = better && covers && h.verify.confidence >= o.verify.confidence + params.replace_better;
      net = net && covers &&
            h_fit >= seen_fit(o.verify, params.verify.min_inliers) - params.alternative_confidence;
      replaced_violations += o.verify.violations;
      // The points the objects explain together (a cell counts once: for its owner).
      for (std::uint32_t c : o.inlier_cells)
        replaced_inliers += cell_owner[c] == static_cast<std::int32_t>(k);
    }
    // ... unless the measured points contradict it more than they contradict the objects it replaces.
    const double h_cells = static_cast<double>(h.inlier_cells.size());
    replace = replace && conflicts > 0 && h_cells >= params.replace_gain * replaced_inliers &&
              h.verify.violations <= replaced_violations + params.replace_violations * h_cells;
    // ... or one that explains about as many of their points with fewer violations and a clearly higher
    // confidence (a smaller model where a larger one claimed matter in seen free space).
    better = better && conflicts > 0 && h_cells >= params.alternative_inliers * replaced_inliers &&
             h.verify.violations < replaced_violations;
    // ... or one whose net count of points (inliers less replace_violation_weight x violations) is at least
    // replace_gain x theirs, its fit of the points in view (seen_fit: what hides part of a larger solid does
    // not count against it) as good: a larger model whose extra part the sensor saw where a smaller one ends.
    // (A gain over a negative count, objects with more violations than half their inliers, is still a gain.)
    const double w = params.replace_violation_weight;
    const double replaced_net = replaced_inliers - w * static_cast<double>(replaced_violations);
    net = net && conflicts > 0 &&
          h_cells - w * h.verify.violations >=
              replaced_net + (params.replace_gain - 1.0) * std::abs(replaced_net);
    replace = replace || better || net;
    if (!replace) {
      out.stats.interpenetrating += solid_clash ? 1 : 0;
      // A look-alike of the one object it conflicts with, on most of its points: an alternative of it.
      if (conflicts == 1)
        for (std::size_t k = 0; k < out.objects.size(); ++k)
          if (conflicts_with(params, k, out) &&
              static_cast<double>(conflict_cells[k]) >=
                  params.replace_cover * static_cast<double>(out.objects[k].inlier_cells.size()))
            list_alternative(params, rz.library_, h.model, h.verify.confidence, h.verify.inliers, h.R, h.t,
                             out.objects[k]);
      return false;
    }
    for (std::size_t k = out.objects.size(); k-- > 0;) {
      if (conflicts_with(params, k, out)) {
        remove_object(out, k);
        ++out.stats.replaced;
      }
    }
  }
  for (const FaceMatch& m : h.matches) node_used[static_cast<std::size_t>(m.scene)] = 1;
  const auto obj_index = static_cast<std::int32_t>(out.objects.size());
  for (std::uint32_t c : h.inlier_cells) cell_owner[c] = obj_index;
  find_alternatives(*this, i, params, h);
  h.gap_checked = false;
  canonical_pose(rz.library_.models[static_cast<std::size_t>(h.model)], h.R, h.t);
  out.objects.emplace_back();
  std::swap(out.objects.back(), spare_objects[out.objects.size() - 1]);
  copy_hypothesis(h, out.objects.back());
  return true;
}

// The inlier cells of the hypotheses still waiting for support that no accepted object owns get `owner`
// (kWaitingOwner while the hidden ones are checked, -1 afterwards).
void Recognizer::Impl::mark_waiting_cells(std::int32_t owner) {
  const std::int32_t from = owner == -1 ? kWaitingOwner : -1;
  for (std::size_t i : deferred)
    if (i != kNoHypothesis)
      for (std::uint32_t c : hyps[i].inlier_cells)
        if (cell_owner[c] == from) cell_owner[c] = owner;
}

namespace {

// The factor that takes `explained` of r's occluded rays out of its confidence's denominator (1 when none).
double occluders_credit(const VerifyResult& r, int explained, double occluded_weight) {
  const double seen = static_cast<double>(r.inliers + r.violations);
  const double before = seen + occluded_weight * static_cast<double>(r.occluded);
  const double after = seen + occluded_weight * static_cast<double>(r.occluded - explained);
  return explained == 0 || after <= 0.0 ? 1.0 : before / after;
}

}  // namespace

// h's confidence when its occluded rays whose measured points belong to other objects (accepted, or waiting
// for support: cell_owner != -1) no longer count against it (fine samples, h's refined pose).
double Recognizer::Impl::confidence_with_occluders(const Hypothesis& h, double occluded_weight) {
  Verifier& v = verifiers.front();
  Mat3 R = h.R;
  Vec3 t = h.t;
  const VerifyResult r = v.verify(fine, geometry[static_cast<std::size_t>(h.model)], R, t, false);
  int explained = 0;
  for (std::uint32_t c : v.occluded_cells()) explained += cell_owner[c] != -1 ? 1 : 0;
  return h.verify.confidence * occluders_credit(r, explained, occluded_weight);
}

void Recognizer::Impl::alternatives_in_hiding(const RecognizeParams& params, std::size_t k,
                                              Recognition& out) {
  Hypothesis& o = out.objects[k];
  o.gap_checked = true;
  if (params.hidden_alternatives <= 0) return;
  if (o.alternatives >= Hypothesis::kMaxAlternatives) return;
  const auto self = static_cast<std::int32_t>(k);
  Verifier& v = verifiers.front();
  const double w_occ = v.params().occluded_weight;
  // The confidence of a pose on a sample set, the occluded rays whose points other objects hold not counted
  // (those o holds are: a look-alike of o hidden behind o's own points is no alternative).
  // The fine check slides a pose along the translation its matched planes left open, as verification does. A
  // pose whose inliers are more than max_shared_inliers another accepted object's points scores 0 (it would
  // not be accepted with that object either).
  auto fit = [&](const SampleSet& samples, const Hypothesis& c, Mat3& R, Vec3& t, bool refine, int& inliers) {
    const ModelGeometry& g = geometry[static_cast<std::size_t>(c.model)];
    const VerifyResult r = refine && c.free_dims == 1 ? v.verify_sliding(samples, coarse, g, R, t, c.free_dir)
                                                      : v.verify(samples, g, R, t, refine);
    int explained = 0, others = 0;
    for (std::uint32_t cell : v.occluded_cells())
      explained += cell_owner[cell] != -1 && cell_owner[cell] != self ? 1 : 0;
    for (std::uint32_t cell : v.inlier_cells())
      others += cell_owner[cell] >= 0 && cell_owner[cell] != self ? 1 : 0;
    inliers = r.inliers;
    if (static_cast<double>(others) > params.max_shared_inliers * static_cast<double>(std::max(1, r.inliers)))
      return 0.0;
    return r.confidence * occluders_credit(r, explained, w_occ);
  };
  // The best coarse fit per other model among the hypotheses on at least half of o's scene faces.
  struct Pick {
    std::size_t index = 0;
    double score = -1.0;
  };
  std::array<Pick, 16> best{};
  const std::size_t budget =
      std::min<std::size_t>(best.size(), static_cast<std::size_t>(params.hidden_alternatives));
  std::size_t picks = 0;
  // At most this many coarse checks per object (in pool order), so a large library's pool stays cheap, and
  // per model the first few of a run of its solutions (ranked best first): 6,744 checks instead of 9,928 in
  // 100 cluttered scenes, the same alternatives listed.
  constexpr int kMaxCoarse = 256;
  constexpr int kPerModel = 4;
  int coarse_checks = 0, run_model = -1, run = 0;
  for (std::size_t j = 0; j < nhyp && coarse_checks < kMaxCoarse; ++j) {
    const Hypothesis& c = hyps[j];
    if (c.model == o.model || (j < alive.size() && !alive[j]) || c.partial_face) continue;
    // On at least half of o's scene faces, and on no face another accepted object holds.
    std::size_t shared = 0;
    bool taken = false;
    for (const FaceMatch& cm : c.matches) {
      bool own = false;
      for (const FaceMatch& m : o.matches) own = own || cm.scene == m.scene;
      shared += own ? 1 : 0;
      taken = taken || (!own && node_used[static_cast<std::size_t>(cm.scene)]);
    }
    if (taken || 2 * shared < o.matches.size()) continue;
    bool listed = false;
    for (const Hypothesis::Alternative& a : o.listed_alternatives()) listed = listed || a.model == c.model;
    if (listed) continue;
    run = c.model == run_model ? run + 1 : 1;
    run_model = c.model;
    if (run > kPerModel) continue;
    Mat3 R = c.R;
    Vec3 t = c.t;
    int inliers = 0;
    ++coarse_checks;
    double score = fit(coarse, c, R, t, false, inliers);
    if (have_table && score >= 0.5 * params.min_confidence)
      score *= support_factor(library->models[static_cast<std::size_t>(c.model)], R, t, table,
                              MeasuredPoints(coarse), support_params(c, score));
    if (score < 0.5 * params.min_confidence) continue;
    // One per model: a better pose of a model already picked replaces it.
    std::size_t slot = picks;
    for (std::size_t q = 0; q < picks; ++q)
      if (hyps[best[q].index].model == c.model) slot = q;
    if (slot < picks) {
      if (score > best[slot].score) best[slot] = {j, score};
      continue;
    }
    if (picks < budget) {
      best[picks++] = {j, score};
      continue;
    }
    std::size_t worst = 0;
    for (std::size_t q = 1; q < picks; ++q)
      if (best[q].score < best[worst].score) worst = q;
    if (score > best[worst].score) best[worst] = {j, score};
  }
  // Those finely, best first, refined, with the support test as o had it, and clear of the other objects.
  std::sort(best.begin(), best.begin() + static_cast<std::ptrdiff_t>(picks),
            [](const Pick& a, const Pick& b) { return a.score > b.score; });
  for (std::size_t q = 0; q < picks && o.alternatives < Hypothesis::kMaxAlternatives; ++q) {
    const Hypothesis& c = hyps[best[q].index];
    const Model& model = library->models[static_cast<std::size_t>(c.model)];
    Mat3 R = c.R;
    Vec3 t = c.t;
    int inliers = 0;
    double conf = fit(fine, c, R, t, true, inliers);
    if (have_table) conf *= support_factor(model, R, t, table, MeasuredPoints(fine), support_params(c, conf));
    // A possible world: it may not interpenetrate the other accepted objects.
    bool clash = false;
    for (std::size_t a = 0; a < out.objects.size() && !clash; ++a) {
      if (a == k) continue;
      const Hypothesis& other = out.objects[a];
      const Interpenetration ip =
          interpenetration(geometry[static_cast<std::size_t>(c.model)], R, t,
                           geometry[static_cast<std::size_t>(other.model)], other.R, other.t);
      clash = ip.depth_mm > params.interpenetration_mm && ip.volume_share > params.interpenetration_share;
    }
    if (!clash) list_alternative(params, *library, c.model, conf, inliers, R, t, o);
  }
}

bool Recognizer::Impl::accept_objects(Recognizer& rz, Scan& scan, int round, Recognition& out) {
  const RecognizeParams& params = rz.params_;
  out.stats.incompatible_pairs +=
      count_incompatible_pairs(std::span<const Hypothesis>(hyps.data(), nhyp), order);
  const std::size_t accepted_before = out.objects.size();
  const int replaced_before = out.stats.replaced;
  auto reject = [&](const Hypothesis& h) {
    ++out.stats.rejected;
    if (h.verify.confidence > scan.best_rejected) {
      scan.best_rejected = h.verify.confidence;
      scan.best_rejected_model = h.model;
    }
  };
  // Two kinds of hypotheses wait for other objects instead of being rejected (objects explained together):
  // - one that passes only if something under it holds it up, until an object it rests on is accepted (the
  //   supporter may come later in the order: it is partly hidden by what it carries);
  // - one that passes only if the measured points in front of it (occluded rays) belong to other objects,
  //   until they do: to accepted objects or to objects waiting for support (what it carries may hide it).
  const double w_occ = verifiers.front().params().occluded_weight;
  deferred.clear();
  hidden_wait.clear();
  for (std::size_t i : order) {
    if (static_cast<int>(out.objects.size()) >= params.max_objects) break;
    Hypothesis& h = hyps[i];
    if (h.partial_face && h.verify.confidence < detail::pass_confidence(h, params)) {
      reject(h);
      continue;
    }
    const bool restored = h.verify.confidence < params.min_confidence && supported_by_accepted(h, out);
    if (h.verify.confidence < params.min_confidence) {
      const VerifyResult& v = h.verify;
      const double seen = static_cast<double>(v.inliers + v.violations);
      if (v.support > 0.0 && v.support < 1.0 && v.confidence / v.support >= params.min_confidence)
        deferred.push_back(i);
      else if (v.occluded > 0 && seen > 0.0 &&
               v.confidence * (seen + w_occ * static_cast<double>(v.occluded)) / seen >=
                   params.min_confidence)
        hidden_wait.push_back(i);
      else
        reject(h);
      continue;
    }
    if (accept_one(params, rz, i, out) && restored) ++out.stats.stacked;
  }
  auto full = [&] { return static_cast<int>(out.objects.size()) >= params.max_objects; };
  for (bool progress = true; progress && !full();) {
    progress = false;
    // The deferred ones, in order, as long as one finds an accepted object to rest on (a stack of several).
    for (std::size_t& i : deferred) {
      if (i == kNoHypothesis || full() || !supported_by_accepted(hyps[i], out)) continue;
      if (accept_one(params, rz, i, out)) {
        ++out.stats.stacked;
        progress = true;
      }
      i = kNoHypothesis;
    }
    // Then the hidden ones, their occluded rays checked against the objects accepted or waiting for support.
    mark_waiting_cells(kWaitingOwner);
    for (std::size_t& i : hidden_wait) {
      if (i == kNoHypothesis || full()) continue;
      Hypothesis& h = hyps[i];
      const double confidence = confidence_with_occluders(h, w_occ);
      if (confidence < std::max(params.min_confidence, params.hidden_min_confidence)) continue;
      h.verify.confidence = confidence;
      if (accept_one(params, rz, i, out)) {
        ++out.stats.hidden;
        alternatives_in_hiding(params, out.objects.size() - 1, out);
        progress = true;
      }
      i = kNoHypothesis;
    }
    mark_waiting_cells(-1);
  }
  // Objects accepted on their own fit whose view other objects partly hide get the same check, now that the
  // round's objects are known (an alternative must not interpenetrate any of them).
  for (std::size_t k = 0; k < out.objects.size(); ++k) {
    const VerifyResult& v = out.objects[k].verify;
    const double rays = static_cast<double>(v.inliers + v.violations + v.occluded);
    if (!out.objects[k].gap_checked && rays > 0.0 &&
        static_cast<double>(v.occluded) >= params.occluded_alternatives_share * rays)
      alternatives_in_hiding(params, k, out);
  }
  for (std::size_t i : deferred)
    if (i != kNoHypothesis) reject(hyps[i]);
  for (std::size_t i : hidden_wait)
    if (i != kNoHypothesis) reject(hyps[i]);
  // Instances: the k-th accepted object of a model is its instance k (replacements may have removed some).
  for (std::size_t k = 0; k < out.objects.size(); ++k) {
    int instance = 0;
    for (std::size_t j = 0; j < k; ++j) instance += out.objects[j].model == out.objects[k].model ? 1 : 0;
    out.objects[k].instance = instance;
  }
  // Give the inlier buffers back to their slots (the next round reuses the hypotheses).
  for (std::size_t k = 0; k < slot_owner.size(); ++k)
    std::swap(hyps[slot_owner[k]].inlier_cells, slot_cells[k]);
  slot_owner.clear();
  if (out.objects.size() == accepted_before && out.stats.replaced == replaced_before && round > 0)
    return false;
  if (static_cast<int>(out.objects.size()) >= params.max_objects) return false;
  return true;
}

void Recognizer::Impl::finish_report(Recognizer& rz, const Scan& scan, Recognition& out) {
  const RecognizeParams& params = rz.params_;
  // Reset the cell owners touched.
  for (const Hypothesis& o : out.objects)
    for (std::uint32_t c : o.inlier_cells) cell_owner[c] = -1;
  if (out.objects.empty()) {
    if (scan.hypotheses_total == 0) {
      out.note = "no reference matched the scene graph";
    } else if (scan.best_rejected_model >= 0) {
      char buf[320];  // formatted without heap temporaries (out.note keeps its reserved capacity)
      std::snprintf(buf, sizeof buf,
                    "no hypothesis passed verification (best: %.200s with confidence %.3f < %.2f)",
                    rz.library_.models[static_cast<std::size_t>(scan.best_rejected_model)].name.c_str(),
                    scan.best_rejected, params.min_confidence);
      out.note.assign(buf);
    } else {
      out.note = "all hypotheses were incompatible";
    }
  }
  // A scene graph beyond the matcher's size: say how it was searched (and what was not).
  if (out.stats.windows > 0 || out.stats.unsearched_faces > 0) {
    char buf[240];
    std::snprintf(buf, sizeof buf,
                  "%sa connected part of %d faces exceeds the matcher's limit: searched in %d overlapping "
                  "windows%s",
                  out.note.empty() ? "" : "; ", out.stats.largest_component, out.stats.windows,
                  out.stats.unsearched_faces > 0 ? ", some faces in none (see stats.unsearched_faces)" : "");
    out.note.append(buf);
  }
}

}  // namespace fs::host::rec
