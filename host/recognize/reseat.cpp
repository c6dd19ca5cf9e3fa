// Recognizer step 4a (beyond the thesis): look-alike placements. A model with near symmetries
// (near_symmetry.hpp) fits the matched faces in several placements; the search keeps a few of them, not
// necessarily the right one (the gyrate rhombicosidodecahedron placed with its gyrated cupola where the scan
// shows an ordinary one; an augmented solid with its augmentation on a hidden side, floating). After its
// coarse check, each plausible hypothesis of such a model is checked in its near-symmetric placements too and
// moves to the one that scores best: the measured points' fit times the support test's factor.
#include <algorithm>

#include "host/recognize/recognizer_impl.hpp"

namespace fs::host::rec {

namespace {

// A placement must fit better than this (coarse confidence) to replace the one the search found: where the
// placements differ only out of view they fit alike, and the search's stays.
constexpr double kReseatMargin = 0.005;

// h's matches under placement T: the scene face matched to model face f now lies on T's preimage of f; false
// when a face the search matched has none, or fewer than half of all matches have one.
bool remapped_matches_hold(const NearSymmetry& T, const Hypothesis& h) {
  std::size_t kept = 0;
  for (const FaceMatch& m : h.matches) {
    const bool has = m.ref >= 0 && static_cast<std::size_t>(m.ref) < T.preimage.size() &&
                     T.preimage[static_cast<std::size_t>(m.ref)] >= 0;
    if (!has && !m.expanded) return false;
    kept += has ? 1 : 0;
  }
  return 2 * kept >= h.matches.size() && kept > 0;
}

// The poses (R1, t1) and (R2, t2) of `m` put it in one place (RecognizeParams::merge_*, symmetries included).
bool same_place(const Model& m, const Mat3& R1, const Vec3& t1, const Mat3& R2, const Vec3& t2,
                const RecognizeParams& p) {
  return ((R1 * m.center + t1) - (R2 * m.center + t2)).norm() <= p.merge_translation_mm &&
         rotation_angle_deg_sym(R1, R2, m) <= p.merge_rotation_deg;
}

}  // namespace

void Recognizer::Impl::reseat(std::size_t index, int worker) {
  Hypothesis& h = hyps[index];
  const auto model = static_cast<std::size_t>(h.model);
  if (near_sym[model].empty() || raw_confidence[index] < reseat_min_confidence) return;
  Verifier& v = verifiers[static_cast<std::size_t>(worker)];
  const ModelGeometry& g = geometry[model];
  // A placement is scored as the recognizer will judge it: its fit times the support test's factor, so of
  // placements that fit alike the one resting on the table (or on something measured) wins over one that
  // floats (an augmented solid whose augmentation the search put on a hidden side instead of underneath).
  const Model& mdl = library->models[model];
  const SupportParams sp = support_params(h, raw_confidence[index]);
  auto support = [&](const Mat3& R, const Vec3& t) {
    return have_table ? support_factor(mdl, R, t, table, MeasuredPoints(coarse), sp) : 1.0;
  };
  double best = raw_confidence[index] * support(h.R, h.t) + kReseatMargin;
  const NearSymmetry* pick = nullptr;
  for (const NearSymmetry& T : near_sym[model]) {
    if (!remapped_matches_hold(T, h)) continue;
    Mat3 R = h.R;
    Vec3 t = h.t;
    apply_near_symmetry(T, R, t);
    // The fit is at most 1: a placement that the support test scales down to `best` or below cannot win, and
    // one that it scales by f must fit better than best / f (a hair less: the product's rounding).
    const double f = support(R, t);
    if (f <= best) continue;
    const double score = v.check_above(coarse, g, R, t, best / f * (1.0 - 1e-12)).confidence * f;
    if (score > best) {
      best = score;
      pick = &T;
    }
  }
  if (!pick) return;
  apply_near_symmetry(*pick, h.R, h.t);
  std::size_t k = 0;
  for (const FaceMatch& m : h.matches) {
    const int from = m.ref >= 0 && static_cast<std::size_t>(m.ref) < pick->preimage.size()
                         ? pick->preimage[static_cast<std::size_t>(m.ref)]
                         : -1;
    if (from >= 0) h.matches[k++] = FaceMatch{m.scene, from, m.expanded};
  }
  h.matches.resize(k);
  // The faces the new placement predicts in view (the planes then refit its translation).
  expand(*hctx, h, worker_pairs[static_cast<std::size_t>(worker)], &node_used);
  h.verify = v.verify(coarse, g, h.R, h.t, false);
  raw_confidence[index] = h.verify.confidence;
  scale_by_explained(h, v.inlier_cells(), false);
  reseated[index] = 1;
}

// Two hypotheses of one model in one place after reseating (several search solutions moved to the same
// placement): the less confident leaves `order`, so copies of one placement do not take the places a scene
// face has in the refinement (RecognizeParams::refine_per_face).
void Recognizer::Impl::drop_reseated_duplicates(const RecognizeParams& params) {
  dropped.assign(nhyp, 0);
  for (std::size_t i : order) {
    if (!reseated[i] || dropped[i]) continue;
    const Hypothesis& a = hyps[i];
    const Model& m = library->models[static_cast<std::size_t>(a.model)];
    for (std::size_t j : order) {
      if (j == i || dropped[j] || hyps[j].model != a.model) continue;
      const Hypothesis& b = hyps[j];
      if (!same_place(m, a.R, a.t, b.R, b.t, params)) continue;
      const bool a_worse =
          a.verify.confidence < b.verify.confidence || (a.verify.confidence == b.verify.confidence && i > j);
      dropped[a_worse ? i : j] = 1;
      if (a_worse) break;
    }
  }
  order.erase(std::remove_if(order.begin(), order.end(), [&](std::size_t i) { return dropped[i] != 0; }),
              order.end());
}

}  // namespace fs::host::rec
