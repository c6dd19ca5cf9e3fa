#pragma once
// From matching solutions to pose hypotheses (thesis ch. 8.1.3 and 9.4.1, plus the pose beyond the thesis):
// translation from the matched planes, expanded solutions (unmatched scene faces that fit a predicted
// reference face), merging of compatible solutions of one list, and helpers of the recognition step.
#include <algorithm>
#include <cmath>
#include <span>
#include <vector>

#include "host/recognize/pose.hpp"
#include "host/recognize/recognizer.hpp"
#include "host/recognize/verify.hpp"

namespace fs::host::rec {

struct HypothesisContext {
  const Library& library;
  const Pfrg& scene;
  const std::vector<int>& scene_index;  // scene node id -> index in scene.nodes, -1 when absent
  Vec3 viewpoint;
  const RecognizeParams& params;
  const ScannerCalibration* scanner = nullptr;  // when known: the laser and the sweep (prescore)
};

// Sets h.t (and free_dims/free_dir) from the planes of h.matches under h.R.
void update_translation(const HypothesisContext& c, Hypothesis& h, std::vector<PlanePair>& scratch);

// Adds unmatched scene faces that coincide with predicted, visible, unmatched model faces (marked expanded),
// then refits the translation. Faces whose id is marked in *taken (by scene node id) are not added. Returns
// the number of faces added.
int expand(const HypothesisContext& c, Hypothesis& h, std::vector<PlanePair>& scratch,
           const std::vector<char>* taken = nullptr);

// Within each model's list (hyps grouped by model: each model's hypotheses contiguous, as the recognizer
// makes them): merges compatible solutions (no shared scene or reference node, similar rotation and
// translation) and drops duplicates (the same object under a symmetry-equivalent pose, overlapping scene
// nodes; the costlier one goes). Returns the number of merges.
int merge_compatible(const HypothesisContext& c, std::span<Hypothesis> hyps, std::vector<char>& alive,
                     std::vector<PlanePair>& scratch);

// Which model faces may stand for a lone scene face: min_area_ratio * area_f <= area_s <= area_ratio * area_f
// + slack.
struct FaceAreaFit {
  double min_area_ratio = 0.7;
  double area_ratio = 1.3;
  double area_slack_mm2 = 30.0;
  bool fits(double area_s, double area_f) const {
    return area_s >= min_area_ratio * area_f && area_s <= area_ratio * area_f + area_slack_mm2;
  }
};

// A scene face within min_tilt_deg of the table's orientation: its pose about the vertical is open
// (top_face_hypotheses); a tilted one gets single_face_hypotheses.
bool parallel_to_table(const PfrgNode& face, const Plane& table, double min_tilt_deg);

// Beyond the thesis: pose hypotheses for a scene face that borders no other scene face (an object that shows
// a single face, e.g. a pyramid lying on a side with only its base turned up). Such an object rests on the
// table on one of its faces g: matching a model face f to the scene face and g to the table gives two normal
// pairs, hence the rotation (when the angle between f and g equals the angle between the scene face and the
// table's downward normal, within angle_tol_deg); the two planes and the scene face's centroid along their
// common line give the translation. Faces parallel to the table (parallel_to_table with min_tilt_deg) are
// skipped, and so are model faces whose area does not fit unless the face may be their seen part
// (SingleFaceParams::hidden_min_area_ratio). Writes at most out.size() hypotheses (model, one match, R, t)
// and returns how many.
struct SingleFaceParams {
  double angle_tol_deg = 2.0;
  double min_tilt_deg = 10.0;
  FaceAreaFit area;
  // A lone face partly hidden by other objects shows less than its model face. When the scene face's extent
  // along the line it shares with the table is known (extent_known: [extent_min, extent_max], its points'
  // coordinates along u = normal x table normal), the model faces too large for `area` but with
  // area_s >= hidden_min_area_ratio x area_f get hypotheses after all the fitting ones (Hypothesis::
  // partial_face): at the centroid, and with either end of the model face's extent along u at the scene
  // face's (one end is the face's edge, the other where the view of it ends). 0 = off.
  double hidden_min_area_ratio = 0.0;
  bool extent_known = false;
  double extent_min = 0.0, extent_max = 0.0;
};
int single_face_hypotheses(const Library& library, const PfrgNode& face, const Plane& table,
                           const SingleFaceParams& p, std::span<Hypothesis> out);

// The same for a lone face parallel to the table (a box or prism seen from above, its sides edge-on): the
// model rests on a face g antiparallel to the matched face f, which leaves the turn about the vertical open.
// It is taken from the outline: `hull` is the convex hull of the scene face's points in the plane basis (u,
// v) (u x v along the face normal, origin anywhere); every pair of long edges of the hull and of f's outer
// polygon gives a candidate turn, each is scored by the mean distance of the hull's vertices to the turned
// polygon's boundary and of the polygon's to the hull's, and the best max_turns per (model, f) within
// max_outline_mm are kept, turns that differ by a symmetry of the model about f's normal counting as one. The
// distance between f and g must equal the face's height above the table within height_tol_mm (raised: be less
// than the height by more than height_tol_mm).
struct TopFaceParams {
  double antiparallel_deg = 2.0;
  FaceAreaFit area;
  double height_tol_mm = 3.0;
  double max_outline_mm = 3.0;
  int max_turns = 2;
  // Instead, the models whose resting face lies higher than the table: on something hidden under them. Such
  // hypotheses are marked Hypothesis::raised and partial_face.
  bool raised = false;
};
int top_face_hypotheses(const Library& library, const PfrgNode& face, const Plane& table,
                        std::span<const Eigen::Vector2d> hull, const Vec3& u, const Vec3& v,
                        const TopFaceParams& p, std::span<Hypothesis> out);

// Convex hull (counter-clockwise, Andrew's monotone chain) of pts in place: pts is sorted and its first k
// entries become the hull; returns k. No allocation.
std::size_t convex_hull_in_place(std::vector<Eigen::Vector2d>& pts, std::vector<Eigen::Vector2d>& scratch);

// Geometric plausibility of a hypothesis before the (costly) low-level verification, in [0, 1]: the share of
// the model's predicted visible area (front faces, weighted down toward grazing view) that matched scene
// faces explain, times a penalty for every matched scene face larger than its model face (a face cannot be
// seen bigger than it is). Ranks the hypotheses of all references so that verification looks at the plausible
// ones first even when the matching costs tie. With the scanner known, a face is predicted only as far as the
// laser lights it (facing the mirror, weighted down toward grazing light) and the sweep and the camera's
// image reach it (share of its points that ScannerCalibration::covers).
double prescore(const HypothesisContext& c, const Hypothesis& h);

// Area of the scene faces the hypothesis matches (mm^2): of two hypotheses with the same prescore, the one
// that explains more of the scene (look-alikes whose visible faces all fit: polycubes).
double matched_scene_area(const HypothesisContext& c, const Hypothesis& h);

// The measured points the support test looks at: a SampleSet's, whose blocks' ray cones let a query about one
// place visit only the blocks that can reach it, or plain points (every one visited).
class MeasuredPoints {
 public:
  MeasuredPoints() = default;
  MeasuredPoints(std::span<const Eigen::Vector3f> points) : points_(points) {}  // NOLINT: implicit on purpose
  MeasuredPoints(const std::vector<Eigen::Vector3f>& points) : points_(points) {}  // NOLINT
  explicit MeasuredPoints(const SampleSet& s)
      : points_(s.points()), blocks_(s.blocks()), from_(s.viewpoint()) {}

  // Calls f(point) for every point whose ray from `from` may lie within `angle` (rad) of the unit direction
  // `dir`, and some others (all of them without blocks, or when `from` is not their viewpoint), in the
  // points' order; stops at the first f that returns true and returns whether one did.
  template <class F>
  bool any_in_cone(const Vec3& from, const Vec3& dir, double angle, F&& f) const {
    // Beyond the blocks' own margin: the float rounding of their directions and angles.
    constexpr double kSlack = 1e-3;
    const bool prune = !blocks_.empty() && from == from_;
    if (!prune) return std::any_of(points_.begin(), points_.end(), f);
    for (const SampleSet::Block& b : blocks_) {
      const double c = std::clamp(b.dir.cast<double>().dot(dir), -1.0, 1.0);
      if (std::acos(c) > static_cast<double>(b.angle) + angle + kSlack) continue;
      for (std::uint32_t k = b.begin; k < b.end; ++k)
        if (f(points_[k])) return true;
    }
    return false;
  }
  std::span<const Eigen::Vector3f> points() const { return points_; }

 private:
  std::span<const Eigen::Vector3f> points_;
  std::span<const SampleSet::Block> blocks_;
  Vec3 from_ = Vec3::Zero();
};

// Support (beyond the thesis): a solid object rests on the table or on something measured just below its
// lowest point. Returns 1 when the model's lowest point in pose (R, t) lies within tol_mm of the table plane
// (normal toward the sensor), or above it with a measured point within radius_mm of that point and more than
// 1 mm lower (not on one of its own seen faces' planes: SupportParams::own_plane_mm), or (look_below) above
// it with the column under its centre of mass hidden from the sensor, from the lowest point's height down (at
// least min_hidden_rays rays of look_below end in front of it, none beyond: what holds a solid at rest is
// under its centre of mass); else `unsupported` (also when it sinks into the table). *lowest receives the
// lowest point's height.
struct SupportParams {
  double tol_mm = 3.0;
  double radius_mm = 6.0;
  double unsupported = 0.5;
  bool look_below = false;
  Vec3 viewpoint = Vec3::Zero();  // the sensor, for look_below and own_plane_mm
  int min_hidden_rays = 0;        // RecognizeParams::hidden_below_min_rays
  // A measured point within this distance of the plane of one of the posed model's faces that turn to the
  // viewpoint holds nothing up: it is that face's scene region going on past the model (the top part of a
  // larger solid, which a smaller model fits, continues below the smaller one's lowest point). 0 = off.
  double own_plane_mm = 0.0;
};
double support_factor(const Model& model, const Mat3& R, const Vec3& t, const Plane& table,
                      const MeasuredPoints& points, const SupportParams& p, double* lowest = nullptr);

// The space under a floating solid, seen from the sensor (beyond the thesis): probe points on the vertical
// under `top` (a point at the height of the solid's lowest point), every 2 mm (more when the solid is high;
// at most 128 probes) from tol_mm below it down to 1 mm above the table. A measured point whose ray from the
// viewpoint passes within 3 mm of a probe point (twice the fine samples' spacing) and ends more than 2 mm
// beyond it counts as `seen_through` (the sensor saw through that space); one that ends more than 2 mm in
// front of a probe it passes, and beyond none, counts as `hidden` (whatever hides that space: other objects,
// or the solid itself). Each ray counts once. A solid resting on an object nothing of which is in view has
// only hidden space under its centre; one floating in front of the table, high enough, has the table seen
// through it.
struct SpaceBelow {
  int hidden = 0;
  int seen_through = 0;
};
SpaceBelow look_below(const Vec3& top, const Plane& table, const Vec3& viewpoint,
                      const MeasuredPoints& points, double tol_mm);

// Height above the table of the posed model's lowest vertex (negative: it sinks into the table); where: that
// vertex.
double lowest_point(const Model& model, const Mat3& R, const Vec3& t, const Plane& table,
                    Vec3* where = nullptr);

// Model faces whose outward normal faces the viewpoint in pose (R, t).
int count_visible_faces(const Model& model, const Mat3& R, const Vec3& t, const Vec3& viewpoint);

// Pairs among the given hypotheses that share a scene node (edges of the incompatibility graph).
int count_incompatible_pairs(std::span<const Hypothesis> hyps, const std::vector<std::size_t>& order);

// Copies without giving up `to`'s buffers.
void copy_hypothesis(const Hypothesis& from, Hypothesis& to);

}  // namespace fs::host::rec
