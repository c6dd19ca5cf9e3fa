// Recognizer step 5 (thesis ch. 9.4): recognition, the greedy extraction of the compatible set that holds the
// best verified hypothesis (no shared scene face, few shared inliers; a reused model is a second instance),
// and the report of an empty result.
#include <algorithm>
#include <cstdio>

#include "host/recognize/recognizer_impl.hpp"

namespace fs::host::rec {

namespace {

// The refined hypotheses of other models that explain the accepted hypothesis h (index `self`) as well: on at
// least half of its scene faces, confidence within alternative_confidence, inliers >= alternative_inliers x
// its own.
void find_alternatives(const Recognizer::Impl& im, std::size_t self, const RecognizeParams& params,
                       Hypothesis& h) {
  h.alternatives = 0;
  for (std::size_t j : im.order) {
    if (h.alternatives >= Hypothesis::kMaxAlternatives) break;
    const Hypothesis& o = im.hyps[j];
    if (j == self || o.model == h.model ||
        o.verify.confidence < h.verify.confidence - params.alternative_confidence ||
        static_cast<double>(o.verify.inliers) <
            params.alternative_inliers * static_cast<double>(h.verify.inliers))
      continue;
    std::size_t shared = 0;
    for (const FaceMatch& m : h.matches)
      for (const FaceMatch& om : o.matches) shared += om.scene == m.scene ? 1 : 0;
    if (2 * shared < h.matches.size()) continue;
    bool listed = false;
    for (const Hypothesis::Alternative& a : h.listed_alternatives()) listed = listed || a.model == o.model;
    if (listed) continue;
    h.alternative[static_cast<std::size_t>(h.alternatives++)] = {o.model, o.verify.confidence};
  }
}

}  // namespace

bool Recognizer::Impl::accept_objects(Recognizer& rz, Scan& scan, int round, Recognition& out) {
  const RecognizeParams& params = rz.params_;
  out.stats.incompatible_pairs +=
      count_incompatible_pairs(std::span<const Hypothesis>(hyps.data(), nhyp), order);
  const std::size_t accepted_before = out.objects.size();
  for (std::size_t i : order) {
    Hypothesis& h = hyps[i];
    if (h.verify.confidence < params.min_confidence) {
      ++out.stats.rejected;
      if (h.verify.confidence > scan.best_rejected) {
        scan.best_rejected = h.verify.confidence;
        scan.best_rejected_model = h.model;
      }
      continue;
    }
    bool clash = false;
    for (const FaceMatch& m : h.matches)
      if (node_used[static_cast<std::size_t>(m.scene)]) clash = true;
    if (!clash && !h.inlier_cells.empty()) {
      std::size_t shared = 0;
      for (std::uint32_t c : h.inlier_cells) shared += cell_owner[c] >= 0 ? 1 : 0;
      clash = static_cast<double>(shared) >
              params.max_shared_inliers * static_cast<double>(h.inlier_cells.size());
    }
    if (clash) continue;
    if (static_cast<int>(out.objects.size()) >= params.max_objects) break;
    for (const FaceMatch& m : h.matches) node_used[static_cast<std::size_t>(m.scene)] = 1;
    const auto obj_index = static_cast<std::int32_t>(out.objects.size());
    for (std::uint32_t c : h.inlier_cells) cell_owner[c] = obj_index;
    int instance = 0;
    for (const Hypothesis& o : out.objects) instance += o.model == h.model ? 1 : 0;
    h.instance = instance;
    find_alternatives(*this, i, params, h);
    canonical_pose(rz.library_.models[static_cast<std::size_t>(h.model)], h.R, h.t);
    out.objects.emplace_back();
    std::swap(out.objects.back(), spare_objects[out.objects.size() - 1]);
    copy_hypothesis(h, out.objects.back());
  }
  // Give the inlier buffers back to their slots (the next round reuses the hypotheses).
  for (std::size_t k = 0; k < slot_owner.size(); ++k)
    std::swap(hyps[slot_owner[k]].inlier_cells, slot_cells[k]);
  slot_owner.clear();
  if (out.objects.size() == accepted_before && round > 0) return false;
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
