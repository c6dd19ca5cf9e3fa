// Recognizer step 3 (thesis ch. 8.1.3, 9.4.1): hypotheses from the search solutions (pose from the rotation
// fit and the matched planes, expansion, compatible merge) and, beyond the thesis, the single-face hypotheses
// of faces that border no other face.
#include <algorithm>
#include <limits>

#include "host/recognize/recognizer_impl.hpp"

namespace fs::host::rec {

using detail::Clock;
using detail::ms_since;

void Recognizer::Impl::make_hypotheses(Recognizer& rz, const HypothesisContext& hc, const Pfrg& graph,
                                       Scan& scan, RecognizeStats& stats) {
  hyp_t0 = Clock::now();
  for (std::size_t i = 0; i < nhyp; ++i) {
    Hypothesis& h = hyps[i];
    update_translation(hc, h, pairs);
    // Expansion takes only faces no accepted object holds.
    stats.expanded_faces += expand(hc, h, pairs, &node_used);
  }
  alive.assign(nhyp, 1);
  stats.merged += merge_compatible(hc, std::span<Hypothesis>(hyps.data(), nhyp), alive, pairs);
  lone_face_hypotheses(rz, graph, stats);
  scan.hypotheses_total += static_cast<int>(nhyp);
  stats.hypotheses = scan.hypotheses_total;
  if (nhyp == 0) stats.verify_ms += ms_since(hyp_t0);
}

// Faces that border no (unexplained) face: single-face hypotheses (model face on it, another on the
// table).
void Recognizer::Impl::lone_face_hypotheses(Recognizer& rz, const Pfrg& graph, RecognizeStats& stats) {
  const RecognizeParams& params = rz.params_;
  raised_waiting = 0;
  if (!(params.single_face_min_area_mm2 > 0 && have_table)) return;
  SingleFaceParams sp;
  if (params.match_area_ratio > 0) {
    sp.area.area_ratio = params.match_area_ratio;
    sp.area.area_slack_mm2 = params.match_area_slack_mm2;
  }
  for (int idx : lone_faces) {
    const PfrgNode& face = graph.nodes[static_cast<std::size_t>(idx)];
    const auto id = static_cast<std::size_t>(face.id);
    // A face parallel to the table that a round of placements on the table left unexplained gets the raised
    // ones (on something hidden under it) in the next round.
    const bool parallel = parallel_to_table(face, table, sp.min_tilt_deg);
    const auto waits_raised = [&] { return parallel && params.single_face_raised && lone_tried[id] == 1; };
    const bool raise = waits_raised();
    if (face.area < params.single_face_min_area_mm2 || (lone_tried[id] && !raise)) continue;
    const std::size_t room =
        std::min(hyps.size() - nhyp, static_cast<std::size_t>(std::max(params.single_face_max, 0)));
    if (room == 0) {  // the pool is full this round: the face is tried again in the next one
      raised_waiting += raise ? 1 : 0;
      continue;
    }
    int n = 0;
    if (!parallel) {
      sp.hidden_min_area_ratio = params.single_face_hidden_min_area_ratio;
      sp.extent_known = false;
      if (sp.hidden_min_area_ratio > 0.0) {
        // The face's extent along its common line with the table, from its fine samples.
        const Vec3 u = face.normal.cross(table.n).normalized();
        outline(face, rz.seg_.labels, u, face.normal.cross(u));
        sp.extent_known = !hull.empty();
        sp.extent_min = std::numeric_limits<double>::infinity();
        sp.extent_max = -sp.extent_min;
        for (const Eigen::Vector2d& q : hull) {
          sp.extent_min = std::min(sp.extent_min, q.x());
          sp.extent_max = std::max(sp.extent_max, q.x());
        }
      }
      n = single_face_hypotheses(rz.library_, face, table, sp,
                                 std::span<Hypothesis>(hyps.data() + nhyp, room));
    } else {
      // Parallel to the table: the turn about the vertical comes from the face's outline (fine samples).
      const Vec3 u = face.normal.unitOrthogonal();
      const Vec3 v = face.normal.cross(u);
      outline(face, rz.seg_.labels, u, v);
      TopFaceParams tp;
      tp.area = sp.area;
      tp.raised = raise;
      n = top_face_hypotheses(rz.library_, face, table, hull, u, v, tp,
                              std::span<Hypothesis>(hyps.data() + nhyp, room));
    }
    nhyp += static_cast<std::size_t>(n);
    stats.single_face += n;
    // Done with this face (1: on the table, 2: raised too) unless its hypotheses were cut short by the room
    // left.
    if (static_cast<std::size_t>(n) < room) lone_tried[id] = raise ? 2 : 1;
    raised_waiting += waits_raised() ? 1 : 0;
  }
  alive.resize(nhyp, 1);
}

void Recognizer::Impl::outline(const PfrgNode& face, const std::vector<std::int32_t>& labels, const Vec3& u,
                               const Vec3& v) {
  hull.clear();
  const auto& cells = fine.cells();
  const auto& pts = fine.points();
  for (std::size_t k = 0; k < cells.size(); ++k)
    if (cells[k] < labels.size() && labels[cells[k]] == face.id - 1) {
      const Vec3 q = pts[k].cast<double>();
      hull.emplace_back(q.dot(u), q.dot(v));
    }
  hull.resize(convex_hull_in_place(hull, hull_scratch));
}

}  // namespace fs::host::rec
