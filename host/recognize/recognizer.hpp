#pragma once
// Recognition (thesis ch. 8-9 and beyond): organized cloud -> segmentation -> scene PFRG (table removed)
// -> inexact matching against every reference -> hypotheses (translation from planes, expansion ch. 8.1.3,
// compatible-solution merge) -> low-level verification + ICP -> merged list, incompatibility graph and the
// best compatible set (ch. 9.4) -> objects.
//
// Memory: a Recognizer sizes its buffers at construction (largest grid, region budget, state budget) and
// reuses them; a warm recognize() performs no heap allocation (see tests/host/recognize).
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "common/calibration.hpp"
#include "host/io/organized_cloud.hpp"
#include "host/library/library.hpp"
#include "host/match/inexact.hpp"
#include "host/match/params.hpp"
#include "host/pfrg/pfrg.hpp"
#include "host/recognize/pose.hpp"
#include "host/recognize/verify.hpp"
#include "host/segment/scene_pfrg.hpp"
#include "host/segment/segment_params.hpp"
#include "host/segment/segmentation.hpp"
#include "host/segment/segmenter.hpp"

namespace fs::host::rec {

struct RecognizeParams {
  match::MatchParams match = match::preset("t9.3");
  seg::SegmentParams segment = seg::SegmentParams::laser();
  // Rows segmented (row_thinning.hpp): 1 = every row; 2 = every other row when the grid's columns (sweep
  // steps) lie at least 1.5 times farther apart than its rows (image rows along the stripe) and no face is
  // reached by only a few rows (else every row). Verification and the reports keep every point either way.
  // 2 changes the outcome of some scenario tests (docs/performance.md, "Every other row for the
  // segmentation"): opt-in.
  int segment_row_step = 1;
  VerifyParams verify;
  int solutions_per_model = 32;  // best solutions of each reference kept as hypotheses (ranked by prescore)
  // Search solutions kept per round over all references: when more come (a scene that nearly every reference
  // of a large library fits, e.g. a box among polycubes), the lowest matching costs are kept (ties: the
  // earlier model in the library) and the others counted (RecognizeStats::solutions_dropped). The
  // recognizer's memory is sized by this (bounded), not by all references' solutions: references are matched
  // in batches of kMatchBatch. <= 0 = by the library: room for kAutoSolutionsPerModel solutions of every
  // reference, at least kAutoMinHypotheses and at most kAutoMaxHypotheses (8,192 up to 2,048 models; 32,608
  // for the 8,152 polycubes, whose look-alikes fit the same view in several correspondences and need more
  // than their best one each: bench_library_scale, 30 scans: top-1 50 % with a pool of 8,192, 73 % with
  // 32,608).
  int max_hypotheses = 0;
  static constexpr int kAutoSolutionsPerModel = 4;
  static constexpr int kAutoMinHypotheses = 8192;
  static constexpr int kAutoMaxHypotheses = 65536;
  // The pool size max_hypotheses gives for a library of `models` references.
  int hypothesis_pool(std::size_t models) const;
  // Match only the references that can hold a solution of the scene part (match::ArcIndex: a reference arc
  // whose normals' angle and face areas pass the rigidity and one-sided area conditions against one of the
  // part's arcs). Exact: the results are those of matching every reference. false = match every reference.
  bool arc_index = true;
  std::int64_t max_states = 10000;  // state budget of one match
  // Start each search only from one face per orbit of the reference's rotation symmetries
  // (face_orbit_representatives): a search started from another face of the orbit finds the same posed
  // solutions, and in a scene with two objects the model fits (a truncated dodecahedron beside an augmented
  // one) those copies took the budget and the solutions of the better fitting one. false = every face.
  bool symmetry_roots = true;
  // A search stops at its first solution (max_solutions). When that solution lies on one object and the
  // scene part holds others, the model is searched once more in the part without that object (its matched
  // faces and the faces around them whose normals its pose predicts): in a pile, the first solution of an
  // elongated pentagonal cupola often lies on the gyroelongated one beside it, and the true one got none.
  bool second_search = true;
  std::int64_t second_search_states = 5000;  // its state budget (a first solution takes a few hundred states)
  // ... only after a first solution of at least this many faces. 4 spares a library of thousands of polycubes
  // (a corner of three faces fits most of them: the second searches doubled the matching time of box-like
  // scenes there) but loses objects among the 120 polyhedra (docs/performance.md).
  int second_search_min_level = 3;
  // TH_solutions of one match (ch. 7.4's "solutions found" stop; the thesis runs t9.3 to exhaustion). A
  // search of a symmetric model otherwise spends its budget on symmetry-equivalent solutions and their
  // sub-matches, and the solutions kept are then picked from thousands of incomplete states. Stopping at the
  // first solution (which keeps the open states of level >= TH_minlevel as incomplete solutions, ch. 7.7.3)
  // is the most accurate setting and faster than a search to exhaustion (measured by bench_recognition).
  // Overrides the match parameters' TH_solutions; 0 = keep theirs.
  std::int64_t max_solutions = 1;
  // Weight of the area dissimilarity in the search cost (alpha, ch. 7.6; t9.3 has 0 because occlusion makes a
  // scene face smaller than its model face). With no attribute in the cost, every correspondence a view
  // allows costs the same and the first solution of a search (max_solutions) is an arbitrary one: among
  // look-alikes (polycubes, every angle 90 deg) the true correspondence is then rarely found. A small weight
  // makes the best-first search try the correspondences whose areas agree first; it adds at most 0.01 to a
  // cost whose threshold (t9.3's TH_cost) is 0.1. Overrides the match parameters' alpha; < 0 = keep theirs.
  double area_cost = 0.01;
  // Solutions whose matched faces cannot lie where the scene's do (consistent_placement, pose.hpp) go after
  // the others of their search, so a model's share of the pool goes to placements that can be right: among
  // polycubes most equal-cost solutions pair a scene face with a parallel model face a cube away.
  // placement.rms_mm <= 0 = off (the matcher's order).
  PlacementCheck placement;
  // Rigidity from level-1 parents (match::MatchParams::rigidity_pairs): the angle between two matched normals
  // is the same in the scene and the reference. Overrides the match parameters' switch when set.
  bool rigidity_pairs = true;
  // TH_omega of the rigidity condition for a laser scan's normals (segmentation normals err by < 1 deg at the
  // bench scanner's noise; t9.3's 20 deg dates from 1990s range data). Against 20 deg: the same recall, also
  // at higher depth noise, with less matching time (measured by bench_recognition). Overrides the match
  // parameters' th_omega_deg; <= 0 = keep theirs.
  double rigidity_deg = 5.0;
  // The table (support plane) is absorbed into the supernode before matching.
  bool remove_table = true;
  double table_angle_deg = 8.0;
  double table_dist_mm = 6.0;
  // Expansion (ch. 8.1.3): an unmatched scene face joins when its plane coincides with a predicted one.
  double expand_angle_deg = 12.0;
  double expand_dist_mm = 6.0;
  double expand_area_ratio = 1.6;  // scene area <= ratio * model face area
  // Compatible-solution merge (ch. 8.1.3 / 9.4.1).
  double merge_rotation_deg = 10.0;
  double merge_translation_mm = 10.0;
  // Support (beyond the thesis): a solid object rests on the table or on something measured below its lowest
  // point. A hypothesis floating higher than support_tol_mm above the table (or sunk below it) with no
  // measured point within support_radius_mm under its lowest point gets its confidence scaled by
  // unsupported_factor (the top part of a taller model seen from above looks like a smaller model), unless it
  // rests on an object accepted in the same decision (a point of its resting face within support_tol_mm of
  // that object's convex surface, that object below it): a part stacked on another hides the face it rests
  // on.
  double support_tol_mm = 3.0;
  double support_radius_mm = 6.0;
  double unsupported_factor = 0.5;
  // A measured point on the plane of one of the solid's own seen faces (within this many mm) does not hold it
  // up: the top part of a larger solid continues there (SupportParams::own_plane_mm). 0 = off.
  double support_own_plane_mm = 0.5;
  // Nor is it scaled when the column under its centre of mass is hidden from the sensor and none of it is
  // seen through (look_below in hypotheses.hpp): it may rest on an object nothing of which is in view. Only
  // for a solid seen clearly: at least hidden_below_min_faces matched faces (or a raised top,
  // Hypothesis::raised) and a fit of hidden_below_min_fit before the factor.
  bool support_hidden_below = true;
  int hidden_below_min_faces = 3;
  double hidden_below_min_fit = 0.9;
  // Rays of measured points that must end in front of that column (none beyond it). 0: no ray need pass it,
  // as when the laser cannot reach what holds the solid up (a scanner whose camera and laser face the objects
  // from opposite sides lights nothing under a stacked solid, and measures no point there;
  // docs/performance.md, "another scanner's geometry").
  int hidden_below_min_rays = 0;
  // A pose the matched planes leave free along a direction that climbs (two faces seen: the translation
  // along their common edge comes from the faces' seen centroids) and whose lowest point ends up to
  // table_snap_mm above the table or below it, beyond support_tol_mm, is also checked moved along that
  // direction onto the table; the move is kept when it fits at most table_snap_slack worse (and keeps
  // VerifyParams::slide_keep_inliers of its inliers): the slide's fit does not know that the pose it leaves
  // floating will fail the support test. 0 = off.
  double table_snap_mm = 8.0;
  double table_snap_slack = 0.02;
  // Acceptance.
  double min_confidence = 0.6;
  // A hypothesis below min_confidence only because of measured points in front of it (occluded rays) is
  // accepted when those points belong to other objects (accepted, or waiting for an object to rest on) and
  // its confidence without them reaches this (an object explained together with others must fit clearly).
  double hidden_min_confidence = 0.9;
  // An object accepted so (its hidden part explained by others) shows little of itself: up to this many
  // hypotheses of other models on its scene faces (the best on the coarse samples, one per model) are
  // checked finely for an alternative. 0 = none; at most 16.
  int hidden_alternatives = 8;
  // The same check for an object accepted on its own fit when at least this share of its rays (fine samples)
  // met measured points in front of it: other objects hide part of it, and a larger solid may hide there too
  // (> 1 = never).
  double occluded_alternatives_share = 0.25;
  double confidence_weight = 0.2;  // ordering key = cost + weight * (1 - confidence)
  // - inlier_weight * inliers / (most inliers of the round's hypotheses): of look-alikes that fit the coarse
  // samples alike, the one explaining the most measured points goes to refinement first.
  double inlier_weight = 0.2;
  double max_shared_inliers = 0.3;  // two objects may not explain more than this share of the same points
  // An accepted object lists as alternatives the other models' verified hypotheses on at least half of its
  // scene faces whose fit is within alternative_confidence of its own (alternative_seen_fit) and whose
  // inliers are at least alternative_inliers x its own (less alternative_inlier_slack).
  double alternative_confidence = 0.02;
  double alternative_inliers = 0.97;
  // ... less this many points: an object seen small (tens of fine samples) differs from a look-alike by a few
  // samples at the ends of its faces, not by what is in view.
  int alternative_inlier_slack = 3;
  // The fits compared leave out the occluded rays (inliers / (inliers + violations), with the same explained
  // share, support factor and few-inliers scaling): what hides both look-alikes does not tell them apart, and
  // a look-alike whose extra part lies behind a neighbour is hit by more rays that the neighbour ends. false
  // = the confidences themselves.
  bool alternative_seen_fit = true;
  int max_objects = 16;
  // A physically possible answer: two accepted solids may not interpenetrate, i.e. overlap by more than
  // interpenetration_share of the smaller one's volume AND by more than interpenetration_mm (the deepest
  // surface point of one inside the other); measured for convex models. Both, since real scenes hold parts
  // whose corner pokes into a neighbour by several mm with ~2 % of its volume (a scan of the independent
  // renderer has 9 mm / 2.3 % in its ground truth), while two models claiming one object overlap by >= 80 %.
  double interpenetration_mm = 2.0;
  double interpenetration_share = 0.05;
  // Replacement: a hypothesis in conflict with accepted objects replaces them when, for each, its confidence
  // is within alternative_confidence of theirs and it explains at least replace_cover of their inlier
  // points, and its inliers number at least replace_gain x theirs together, with no more violations (free
  // space seen where it claims matter) than theirs + replace_violations x its inliers.
  double replace_cover = 0.5;
  double replace_gain = 1.1;
  double replace_violations = 0.01;
  // ... or when it explains at least alternative_inliers x their inliers with fewer violations and a
  // confidence at least replace_better above each of theirs (a better fit of the same points).
  double replace_better = 0.03;
  // ... or when it explains replace_cover of each one's points and its inliers less this many per violation
  // number at least replace_gain x theirs (less as many per violation of theirs), with a fit of the points in
  // view (seen_fit) within alternative_confidence of each of theirs: the points decide between a larger model
  // and the smaller one whose part of it was accepted. 0 = off.
  double replace_violation_weight = 2.0;
  // Faces one searched part of the scene graph may hold; a connected part with more is searched in
  // overlapping windows of this many faces. 0 = the matcher's limit (match::kMaxNodes minus the supernodes);
  // a larger value is clamped to it.
  int max_part_faces = 0;
  // Look-alike placements (beyond the thesis, near_symmetry.hpp): a model whose surface a rigid motion maps
  // onto itself for at least this share of its area, without a symmetry (the gyrate rhombicosidodecahedron
  // and the rhombicosidodecahedron's rotations; the augmented truncated tetrahedron's body, 49 %), fits the
  // matched faces in several placements that differ elsewhere. A plausible hypothesis of such a model (coarse
  // confidence >= min_confidence / 2) is checked in each of them and moves to the one that scores best (fit x
  // the support test's factor). 0 = off.
  double near_symmetry_share = 0.4;
  // Hypotheses checked against the cloud (highest prescore first). Look-alikes (a library of polycubes) give
  // hundreds of hypotheses that fit the same faces equally before verification; a larger budget finds the
  // true one among them more often (bench_library_scale: 1,230 polycubes, 59 % top-1 at 96 / 16, 70 % at
  // 256 / 64, 76 % at 1000 / 1000).
  int max_verified = 256;
  double prescore_area_slack =
      1.1;                   // a scene face may be this much larger than its model face (segmentation)
  int max_refined = 24;      // of those, the most plausible refined by ICP and verified finely
  int verify_per_face = 64;  // a scene face stops drawing hypotheses into verification after this many
  // Screening: when there are more hypotheses than max_verified, up to max_screened of them (highest
  // prescore first, screen_per_face per scene face) are first checked on a sparse sample set (a quarter of
  // the coarse one) and the budget goes to the best screened first, then to the unscreened rest in prescore
  // order (a face the screening did not reach keeps its share). Look-alikes tie in the prescore (a
  // polycube's visible faces fit hundreds of others); the measured points tell them apart. 0 = no screening.
  int max_screened = 2048;
  int screen_per_face = 512;
  // When all hypotheses fit in max_verified, all are checked, past verify_per_face: the prescore does not
  // know what hides an object, so a partly hidden one ranks below the look-alikes that share its faces
  // (pentagons, triangles), however many faces it matches.
  bool check_all_that_fit = true;
  int refine_per_face = 3;  // ... and into refinement
  // A hypothesis that shares a scene face with a refinement pick of its own model (another placement of it)
  // gets its share of that face's refinements after the other models' whose coarse confidence is at most
  // refine_wait_margin lower: a look-alike, or the true model whose coarse pose sits worse, gets a slot too.
  bool refine_models_first = true;
  double refine_wait_margin = 0.05;
  // A scene face whose refined hypotheses all fail the fine check gets refine_per_face more of those whose
  // coarse confidence is within this margin of its best (in the refinement slots left). < 0 = off.
  double refine_again_margin = 0.05;
  // Matching prunes a pair whose scene face is larger than area_ratio x its model face + slack (a face cannot
  // be seen bigger than it is; segmentation may add a rim): match::MatchParams::th_area_ratio. <= 0 = off.
  double match_area_ratio = 1.3;
  double match_area_slack_mm2 = 30.0;
  // ... compared with the model face's area plus its neighbours' across folds of up to this angle (degrees,
  // at most match::kAreaFoldMaxDeg; 0 = the face alone): region growing (SegmentParams::angle_deg 15) follows
  // a fold that shallow, and one scene face then covers a square of an elongated rotunda and a triangle
  // beside it.
  double match_area_fold_deg = 15.0;
  int min_level = 3;  // faces a search solution must match (TH_minlevel, as in the thesis)
  // Beyond the thesis: a connected part of the scene graph with fewer faces than min_level but at least this
  // many (a tetrahedron or pyramid showing two faces) is searched with TH_minlevel = its face count; its
  // solutions then carry the rotation of two non-parallel planes and go through the same verification.
  // 0 = such parts are not searched (the thesis).
  int small_part_min_level = 2;
  // Beyond the thesis: a scene face that borders no other scene face (an object showing one face) gets
  // single-face hypotheses (hypotheses.hpp: single_face_hypotheses; needs the table). Lone faces smaller than
  // single_face_min_area_mm2 are ignored; <= 0 = off. At most single_face_max hypotheses per face.
  double single_face_min_area_mm2 = 300.0;
  int single_face_max = 384;
  // A tilted lone face that other objects partly hide shows less than its model face: larger model faces,
  // down to this ratio of scene to model area, are also tried, placed at the face's centroid and with either
  // end of the model face at an end of the seen one (SingleFaceParams::hidden_min_area_ratio). So little of
  // such an object is in view that one is accepted only at single_face_hidden_min_confidence, its confidence
  // as verified (before the credit for rays that other objects end in front of it). 0 = off.
  double single_face_hidden_min_area_ratio = 0.35;
  double single_face_hidden_min_confidence = 0.9;
  // A lone face parallel to the table that no placement on the table explains may be the top of an object
  // resting on one it hides: in the next round it gets placements of the models that fit it and stand lower
  // than it (TopFaceParams::raised). Like the partly hidden ones, these are accepted only at
  // single_face_hidden_min_confidence, and only when the support test finds them held up by measured points
  // or by hidden space under them (support_hidden_below, which such a placement may use with one face). The
  // next round is a round of its own (rounds >= 2; its graph needs small_part_min_level > 0): a round that
  // accepts nothing leads to it while such faces wait.
  bool single_face_raised = true;
  // Rounds of matching + verification (beyond the thesis): after the first, the faces that no accepted object
  // explains are searched again with TH_minlevel = small_part_min_level and single-face hypotheses, until a
  // round accepts nothing new. 1 = the first round only.
  int rounds = 3;
  int threads = 0;  // matching threads (0 = all cores)
};

struct FaceMatch {
  int scene = 0;  // scene PFRG node id
  int ref = 0;    // model face index (= reference PFRG node id)
  bool expanded = false;
};

struct Hypothesis {
  int model = -1;         // index into the library
  int rank = 0;           // rank of its solution in its model's list
  int part_rank = 0;      // its solution is the k-th kept of its model in its scene part (0 = the best)
  std::vector<int> path;  // search-tree path of its solution: state id "<model>.9.1.1"
  std::vector<FaceMatch> matches;
  int level = 0;          // faces matched by the search
  int faces_visible = 0;  // model faces facing the sensor in this pose
  Mat3 R = Mat3::Identity();
  Vec3 t = Vec3::Zero();
  int free_dims = 0;  // translation directions the matched planes left open
  Vec3 free_dir = Vec3::Zero();
  double cost = 0.0;  // matching cost (ch. 7.6)
  double rotfit_error = 0.0;
  bool degenerate = false;
  VerifyResult verify;
  double key = 0.0;           // ordering key
  double prescore = 0.0;      // geometric plausibility before verification (see hypotheses.hpp)
  double matched_area = 0.0;  // area of the scene faces it matches (mm^2): ties of the prescore
  double screened = -1.0;     // confidence on the screening samples (-1: not screened; RecognizeParams)
  int screened_inliers = 0;   // ... and its inliers there
  int instance = 0;           // 0 = first instance of its model, 1 = second, ...
  bool merged = false;        // a compatible solution was merged into it
  // A single-face hypothesis whose model face is larger than the scene face (SingleFaceParams::
  // hidden_min_area_ratio) or a raised top (TopFaceParams::raised): accepted, listed as an alternative and
  // counted as a face's passing refinement only at RecognizeParams::single_face_hidden_min_confidence.
  bool partial_face = false;
  // A raised top (TopFaceParams::raised, also partial_face): it rests on what it hides, so space hidden under
  // it may hold it up with its one face (RecognizeParams::support_hidden_below).
  bool raised = false;
  // Other models that fit this view as well (same scene faces, confidence and inliers within
  // RecognizeParams::alternative_*): the parts where they differ are out of view. Accepted objects only.
  struct Alternative {
    int model = -1;
    double fit = 0.0;           // its verification confidence
    Mat3 R = Mat3::Identity();  // its pose (x_scene = R x_model + t; canonical, as the object's)
    Vec3 t = Vec3::Zero();
  };
  static constexpr int kMaxAlternatives = 4;
  std::array<Alternative, kMaxAlternatives> alternative{};
  int alternatives = 0;  // listed in alternative[0 .. alternatives)
  // Accepted objects: the larger solids that may hide behind its occluders were checked
  // (alternatives_in_hiding).
  bool gap_checked = false;
  std::span<const Alternative> listed_alternatives() const {
    return {alternative.data(), static_cast<std::size_t>(alternatives)};
  }
  // Ambiguity (issue #20): an object that lists an alternative is ambiguous, "this is X or Y": the view fits
  // each candidate (the object's model and its alternatives). The fit of a candidate is its verification
  // confidence (verify.confidence for the object's model); its confidence is its fit times its share of the
  // candidates' fits, fit * fit / (sum of the candidates' fits). So an unambiguous object's confidence is its
  // fit, and two models that fit alike get about half of it each.
  bool ambiguous() const { return alternatives > 0; }
  double fit() const { return verify.confidence; }
  double candidate_confidence(double candidate_fit) const {
    double sum = verify.confidence;
    for (const Alternative& a : listed_alternatives()) sum += a.fit;
    return sum > 0.0 ? candidate_fit * candidate_fit / sum : 0.0;
  }
  double confidence() const { return alternatives > 0 ? candidate_confidence(verify.confidence) : fit(); }
  std::vector<std::uint32_t> inlier_cells;
};

struct RecognizeStats {
  double segment_ms = 0, pfrg_ms = 0, match_ms = 0, verify_ms = 0, total_ms = 0;
  int segment_row_step = 1;  // rows segmented: every row (1) or every other (2; RecognizeParams)
  int regions = 0, known_regions = 0, scene_nodes = 0, scene_arcs = 0;
  int components = 0;  // connected parts of the scene graph searched (>= min_level faces)
  // A connected part of more faces than the matcher takes is searched in overlapping windows (counted here,
  // with its size); faces beyond every part slot are not searched (counted; 0 in any normal scene).
  int windows = 0, largest_component = 0, unsearched_faces = 0;
  bool table_removed = false;
  int references = 0;
  std::int64_t states = 0;  // search states over all references
  int hypotheses = 0, merged = 0, expanded_faces = 0, rejected = 0, incompatible_pairs = 0;
  int single_face = 0;       // hypotheses of faces that border no other face (in hypotheses)
  int rounds = 0;            // matching + verification rounds run
  int replaced = 0;          // accepted objects replaced by one model explaining their points and more
  int interpenetrating = 0;  // hypotheses refused because their solid would interpenetrate an accepted one
  int stacked = 0;           // objects accepted because they rest on another accepted object (support test)
  int hidden = 0;            // objects accepted because other objects explain the points in front of them
  int reseated = 0;          // hypotheses moved to a near-symmetric placement (RecognizeParams)
  std::int64_t references_searched = 0;  // references matched against some part (all rounds; arc_index)
  std::int64_t solutions = 0;            // search solutions of all references (all rounds)
  std::int64_t solutions_dropped = 0;    // of those, beyond RecognizeParams::max_hypotheses (the worst costs)
};

struct Recognition {
  std::vector<Hypothesis> objects;  // best first
  RecognizeStats stats;
  std::string note;  // why the list is empty (or other remarks)
};

class Recognizer {
 public:
  Recognizer(const Library& library, const RecognizeParams& params, std::size_t max_cells = 512 * 1024);
  ~Recognizer();
  // table: the support plane when known (e.g. from a scan's calibration); nullptr = the largest plane facing
  // the sensor is taken as the table when remove_table is set.
  const Recognition& recognize(const OrganizedCloud& cloud, const Plane* table = nullptr);

  // Intermediate results of the last recognize() (for reports and `facetscan graph`).
  const seg::Segmentation& segmentation() const { return seg_; }
  const Pfrg& scene_graph() const { return scene_; }
  const Library& library() const { return library_; }
  const RecognizeParams& params() const { return params_; }
  // The verified hypotheses of the last recognize(), in ordering-key order (diagnostics, reports).
  std::vector<const Hypothesis*> candidates() const;
  // Every hypothesis of the last recognize() that survived the compatible merge (diagnostics).
  std::vector<const Hypothesis*> all_hypotheses() const;
  // The table (support plane) the last recognize() found and removed, normal toward the sensor; nullptr when
  // none (for reports).
  const Plane* table() const;
  // Cell -> object index (into objects) or -1, for colouring.
  void object_labels(const OrganizedCloud& cloud, std::vector<std::int32_t>& labels) const;

  struct Impl;  // opaque (recognizer_impl.hpp)

 private:
  const Library& library_;
  RecognizeParams params_;
  seg::Segmenter segmenter_;
  seg::Segmenter thin_segmenter_;  // every other row (RecognizeParams::segment_row_step)
  OrganizedCloud thin_cloud_;
  seg::Segmentation thin_seg_;
  seg::ScenePfrgBuilder pfrg_builder_;
  seg::Segmentation seg_;
  Pfrg scene_;
  std::unique_ptr<Impl> impl_;
  Recognition result_;
};

// The match parameters of the first round's searches (RecognizeParams::match with the recognizer's overrides:
// state budget, TH_minlevel, TH_solutions, rigidity pairs and TH_omega, one-sided area condition).
match::MatchParams match_params(const RecognizeParams& params);

// Recognition JSON (DESIGN.md contract): {"objects":[{"model","rotation","translation","cost","confidence",
// "fit","ambiguous","faces_matched","faces_visible","matches",...}],"stats":{...}}; an ambiguous object adds
// "candidates" and "alternatives" (Hypothesis::confidence()).
nlohmann::json to_json(const Recognition& r, const Library& library);

}  // namespace fs::host::rec
