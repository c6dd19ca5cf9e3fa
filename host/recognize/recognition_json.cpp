#include <nlohmann/json.hpp>

#include "host/match/inexact.hpp"
#include "host/recognize/recognizer.hpp"

namespace fs::host::rec {

nlohmann::json to_json(const Recognition& r, const Library& library) {
  nlohmann::json objects = nlohmann::json::array();
  for (const Hypothesis& h : r.objects) {
    const Model& m = library.models[static_cast<std::size_t>(h.model)];
    nlohmann::json o;
    o["model"] = m.name;
    o["instance"] = h.instance;
    o["rotation"] = {{h.R(0, 0), h.R(0, 1), h.R(0, 2)},
                     {h.R(1, 0), h.R(1, 1), h.R(1, 2)},
                     {h.R(2, 0), h.R(2, 1), h.R(2, 2)}};
    o["translation"] = {h.t.x(), h.t.y(), h.t.z()};
    o["cost"] = h.cost;
    // Ambiguity-aware (Hypothesis::confidence()): the fit when the view tells the model apart, its share of
    // the candidates' when it does not.
    o["confidence"] = h.confidence();
    o["fit"] = h.fit();
    o["ambiguous"] = h.ambiguous();
    int searched = 0;
    for (const FaceMatch& fm : h.matches) searched += fm.expanded ? 0 : 1;
    o["faces_matched"] = static_cast<int>(h.matches.size());
    o["faces_matched_by_search"] = searched;
    o["faces_visible"] = h.faces_visible;
    nlohmann::json matches = nlohmann::json::array();
    nlohmann::json expanded = nlohmann::json::array();
    for (const FaceMatch& fm : h.matches) {
      matches.push_back({fm.scene, fm.ref});
      if (fm.expanded) expanded.push_back({fm.scene, fm.ref});
    }
    o["matches"] = matches;
    o["expanded_matches"] = expanded;
    o["state"] = match::state_id(m.name, h.path);
    o["rotfit_error"] = h.rotfit_error;
    o["merged"] = h.merged;
    if (h.free_dims > 0) {
      o["translation_underdetermined"] = {{"dims", h.free_dims},
                                          {"direction", {h.free_dir.x(), h.free_dir.y(), h.free_dir.z()}}};
    }
    if (h.ambiguous()) {
      // The candidates, the object's model first; "alternatives" = the others (as before this list).
      // Each with its own pose: look-alikes of other shapes sit differently on the same visible faces.
      auto candidate = [&](int model, double fit, const Mat3& R, const Vec3& t) {
        return nlohmann::json{
            {"model", library.models[static_cast<std::size_t>(model)].name},
            {"confidence", h.candidate_confidence(fit)},
            {"fit", fit},
            {"rotation",
             {{R(0, 0), R(0, 1), R(0, 2)}, {R(1, 0), R(1, 1), R(1, 2)}, {R(2, 0), R(2, 1), R(2, 2)}}},
            {"translation", {t.x(), t.y(), t.z()}}};
      };
      nlohmann::json candidates = nlohmann::json::array({candidate(h.model, h.fit(), h.R, h.t)});
      nlohmann::json alts = nlohmann::json::array();
      for (const Hypothesis::Alternative& a : h.listed_alternatives()) {
        candidates.push_back(candidate(a.model, a.fit, a.R, a.t));
        alts.push_back(candidate(a.model, a.fit, a.R, a.t));
      }
      o["candidates"] = std::move(candidates);
      o["alternatives"] = std::move(alts);
    }
    o["verification"] = {{"inliers", h.verify.inliers},   {"violations", h.verify.violations},
                         {"occluded", h.verify.occluded}, {"hits", h.verify.hits},
                         {"coverage", h.verify.coverage}, {"explained", h.verify.explained},
                         {"rms_mm", h.verify.rms_mm},     {"icp_iterations", h.verify.refine_iterations}};
    objects.push_back(std::move(o));
  }
  const RecognizeStats& s = r.stats;
  nlohmann::json stats = {{"segment_ms", s.segment_ms},
                          {"segment_row_step", s.segment_row_step},
                          {"pfrg_ms", s.pfrg_ms},
                          {"match_ms", s.match_ms},
                          {"verify_ms", s.verify_ms},
                          {"total_ms", s.total_ms},
                          {"regions", s.regions},
                          {"known_regions", s.known_regions},
                          {"scene_nodes", s.scene_nodes},
                          {"scene_arcs", s.scene_arcs},
                          {"table_removed", s.table_removed},
                          {"components", s.components},
                          {"windows", s.windows},
                          {"largest_component", s.largest_component},
                          {"unsearched_faces", s.unsearched_faces},
                          {"references", s.references},
                          {"states", s.states},
                          {"hypotheses", s.hypotheses},
                          {"references_searched", s.references_searched},
                          {"solutions", s.solutions},
                          {"solutions_dropped", s.solutions_dropped},
                          {"merged", s.merged},
                          {"expanded_faces", s.expanded_faces},
                          {"single_face", s.single_face},
                          {"rounds", s.rounds},
                          {"replaced", s.replaced},
                          {"interpenetrating", s.interpenetrating},
                          {"stacked", s.stacked},
                          {"hidden", s.hidden},
                          {"reseated", s.reseated},
                          {"rejected", s.rejected},
                          {"incompatible_pairs", s.incompatible_pairs}};
  nlohmann::json j = {{"objects", objects}, {"stats", stats}};
  if (!r.note.empty()) j["note"] = r.note;
  return j;
}

}  // namespace fs::host::rec
