#pragma once
// Low-level verification of a pose hypothesis against the measured organized cloud (beyond the thesis, its
// outlook ch. 10): every sampled measured point's sensor ray is cast against the model's faces in that pose.
//   inlier     the measured point lies on the predicted surface (|range - predicted| <= inlier_mm)
//   violation  the sensor saw through the predicted surface (range > predicted + inlier_mm): free space where
//              the hypothesis claims matter
//   occluded   the measured point lies in front of the predicted surface (something else hides the object)
// The pose is refined by point-to-plane ICP on the inliers (each assigned to its face's plane).
// confidence = inliers / (inliers + violations + occluded_weight * occluded), scaled down when the inliers
// are too few to carry the claim.
#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>

#include "common/calibration.hpp"
#include "host/io/organized_cloud.hpp"
#include "host/library/model.hpp"
#include "host/recognize/convex_clip.hpp"

namespace fs::host::rec {

struct VerifyParams {
  double inlier_mm = 2.0;          // range tolerance of an inlier (also the violation margin)
  int sample_step = 2;             // use every n-th row and column (at least)
  double sample_spacing_mm = 1.5;  // > 0: fine samples about this far apart on the surface (coarse: twice)
  int icp_iterations = 6;          // 0 = no refinement
  double icp_max_dist_mm = 4.0;    // point-to-plane distance for ICP correspondences
  double occluded_weight = 0.25;
  int min_inliers = 30;  // fewer inliers scale the confidence down linearly
  // Line search along an unconstrained translation direction (verify_sliding): offsets up to slide_range_mm
  // in slide_step_mm steps, then half steps around the best; kept if the confidence gains > slide_gain.
  double slide_range_mm = 8.0;
  double slide_step_mm = 1.0;
  double slide_gain = 0.005;
  // An offset is taken only when it explains at least this share of the inliers of the pose it slides from
  // (1 = as many): sliding off the seen faces must not buy a better fit by explaining less.
  double slide_keep_inliers = 0.95;
  // Then, on the fine samples, steps of a quarter slide_step_mm halved down to slide_fine_mm: where the
  // planes leave the pose free, only the points at the ends of the seen faces place it, and a pose 0.2 mm
  // off loses a few percent of its inliers to the range tolerance there (a look-alike placed better then
  // wins). 0 = off.
  double slide_fine_mm = 0.0625;
};

struct VerifyResult {
  int hits = 0, inliers = 0, violations = 0, occluded = 0;
  double rms_mm = 0.0;  // rms point-to-plane distance of the inliers after refinement
  double confidence = 0.0;
  double coverage = 0.0;   // inliers / hits
  double explained = 1.0;  // share of the matched scene regions' samples that are inliers (recognizer)
  double support = 1.0;    // 1 = rests on the table or on measured surface below it (recognizer)
  double lowest_mm = 0.0;  // height of the model's lowest point above the table (when one is known)
  int refine_iterations = 0;
};

// Per-model geometry prepared once (face planes, in-plane bases and 2D polygon loops in the model frame).
class ModelGeometry {
 public:
  explicit ModelGeometry(const Model& model);
  // Ray (model frame) -> nearest front-facing face hit: distance along the unit direction and face index;
  // returns -1 when it misses.
  int cast(const Vec3& origin, const Vec3& dir, double& distance) const;
  // The same for rays from one origin, over the faces front_faces(origin) listed (those whose plane has the
  // origin on its outer side: no other face can be hit from the front).
  // in_sphere: the caller has found the ray well inside the bounding sphere (its own test, with a margin far
  // above the rounding), and the cast's test is skipped.
  int cast(const Vec3& origin, const Vec3& dir, double& distance, std::span<const std::uint32_t> faces,
           bool in_sphere = false) const;
  void front_faces(const Vec3& origin, std::vector<std::uint32_t>& out) const;
  // Convex models (closed: convex() is false for an open one): the same hit as cast() without a polygon test,
  // by clipping the ray against every face's half-space (the ray enters through the face of the latest entry,
  // and hits when no face lets it out before; convex_clip.hpp, four faces at a time). faces:
  // clip_faces(origin).
  int cast_convex(const Vec3& origin, const Vec3& dir, double& distance, const ClipFaces& faces,
                  bool in_sphere = false) const;
  void clip_faces(const Vec3& origin, ClipFaces& out) const;
  const Model& model() const { return *model_; }
  double radius() const { return radius_; }
  const Vec3& center() const { return center_; }
  bool convex() const { return convex_; }
  // Points on the model's surface (model frame): every face's vertices, centroid and a grid over it about
  // radius / 12 apart. any_surface_sample(f) calls f(point) on each in turn until f returns true (true when
  // one did). A convex model keeps them (the interpenetration test of two posed convex models samples one
  // against the other); a non-convex model makes them as they are asked for (the support test, rarely), so a
  // library of thousands of non-convex parts does not hold them all (about 25 KB per polycube).
  template <class F>
  bool any_surface_sample(F&& f) const {
    if (convex_) {
      for (const Vec3& s : surface_)
        if (f(s)) return true;
      return false;
    }
    return each_surface_point(f);
  }
  const std::vector<Vec3>& surface_samples() const { return surface_; }  // convex models only (else empty)
  // How deep a point (model frame) lies inside a convex model: the smallest distance to a face plane,
  // negative outside. 0 for a non-convex model (not tested).
  double depth_inside(const Vec3& p) const;
  // Points filling a convex model's volume on a grid (model frame), empty for a non-convex model.
  const std::vector<Vec3>& volume_samples() const { return volume_; }
  // Convex models: whether one of this model's face planes has every vertex of `other` (x = R x_other + t in
  // this model's frame) more than `margin` mm on its outer side: a plane that separates the two solids.
  // False for a non-convex model or one without vertices.
  bool separated_from(const ModelGeometry& other, const Mat3& R, const Vec3& t, double margin) const;

 private:
  struct Face {
    Vec3 n, u, v;
    double offset;
    std::vector<Eigen::Vector2d> pts;       // all loops' vertices, concatenated
    std::vector<std::uint32_t> loop_start;  // start index of each loop in pts (+ end sentinel)
    Eigen::Vector2d lo, hi;                 // 2D bounding box
    // One convex counter-clockwise loop: inside = every edge's inward normal . q >= its offset (no division).
    bool convex = false;
    std::vector<Eigen::Vector3d> edges;  // (inward normal x, y, offset) per edge
  };
  bool inside(const Face& f, const Eigen::Vector2d& q) const;
  bool misses_bounding_sphere(const Vec3& origin, const Vec3& dir) const;  // the ray (unit dir) passes it by
  template <class F>
  bool each_surface_point(F&& f) const;
  void sample_surface();
  void sample_volume();
  std::vector<Vec3> surface_, volume_;
  std::vector<Vec3> vertices_;  // distinct face-loop vertices (convex models)
  const Model* model_;
  std::vector<Face> faces_;
  std::vector<std::uint32_t> all_faces_;  // 0 .. faces - 1
  Vec3 center_;
  double radius_;
  bool convex_ = false;
};

template <class F>
bool ModelGeometry::each_surface_point(F&& f) const {
  const double spacing = std::max(1.0, radius_ / 12.0);
  for (std::size_t i = 0; i < faces_.size(); ++i) {
    const Face& fc = faces_[i];
    const ModelFace& mf = model_->faces[i];
    if (f(mf.centroid)) return true;
    for (const auto& loop : mf.loops)
      for (const Vec3& p : loop)
        if (f(p)) return true;
    for (double x = fc.lo.x() + 0.5 * spacing; x < fc.hi.x(); x += spacing)
      for (double y = fc.lo.y() + 0.5 * spacing; y < fc.hi.y(); y += spacing)
        if (inside(fc, Eigen::Vector2d(x, y)) && f(Vec3(x * fc.u + y * fc.v + fc.offset * fc.n))) return true;
  }
  return false;
}

// Mean distance (mm) between depth-continuous neighbours along a grid row (x) and column (y) of an organized
// cloud, from a subsample; 0 where unknown (unorganized cloud, no such neighbours).
Eigen::Vector2d grid_spacing_mm(const OrganizedCloud& cloud);

// Every col-th column and row-th row. spacing_mm > 0: the steps grow from sample_step until neighbouring
// samples are about that far apart on the surface (grid = grid_spacing_mm), so the work does not grow with
// the scan's resolution.
struct SampleSteps {
  std::uint32_t col = 1, row = 1;
};
SampleSteps sample_steps(const Eigen::Vector2d& grid, int sample_step, double spacing_mm);

// The measured points verification looks at: the valid cells at the SampleSteps, grouped in blocks of
// neighbouring samples with the cone of their viewing rays, so a hypothesis only visits the blocks whose rays
// can meet its bounding sphere. Built once per scan; no allocation once warm.
class SampleSet {
 public:
  void reserve(std::size_t max_cells);
  void build(const OrganizedCloud& cloud, SampleSteps steps, int block = 8);
  struct Block {
    std::uint32_t begin = 0, end = 0;                // range in points()
    Eigen::Vector3f dir = Eigen::Vector3f::UnitZ();  // mean viewing direction (unit)
    float angle = 0.0f;                              // max angle (rad) between a member's ray and dir
  };
  // A point's ray from the viewpoint: unit direction and range (range 0: the point is the viewpoint).
  struct Ray {
    Vec3 dir = Vec3::UnitZ();
    double range = 0.0;
  };
  const std::vector<Eigen::Vector3f>& points() const { return points_; }
  const std::vector<Ray>& rays() const { return rays_; }  // one per point
  const std::vector<std::uint32_t>& cells() const { return cells_; }
  const std::vector<Block>& blocks() const { return blocks_; }
  const Vec3& viewpoint() const { return viewpoint_; }

 private:
  std::vector<Eigen::Vector3f> points_;
  std::vector<Ray> rays_;
  std::vector<std::uint32_t> cells_;
  std::vector<Block> blocks_;
  Vec3 viewpoint_ = Vec3::Zero();
};

// How two posed models (x_world = R x + t) interpenetrate: the share of the smaller one's volume inside the
// other (0..1) and the deepest surface point of one inside the other (mm). Both 0 when they do not overlap;
// measured against convex models only (0 when a non-convex one is involved).
struct Interpenetration {
  double volume_share = 0.0;
  double depth_mm = 0.0;
};
Interpenetration interpenetration(const ModelGeometry& a, const Mat3& Ra, const Vec3& ta,
                                  const ModelGeometry& b, const Mat3& Rb, const Vec3& tb);

class Verifier {
 public:
  explicit Verifier(const VerifyParams& params = {}) : params_(params) {}
  // Sizes the internal buffers for up to `samples` points and models of up to `faces` faces (a warm verify()
  // then never allocates).
  void reserve(std::size_t samples, std::size_t faces) {
    front_.reserve(faces);
    clip_.reserve(faces);
    inlier_cells_.reserve(samples);
    occluded_cells_.reserve(samples);
    inlier_sample_.reserve(samples);
    inlier_face_.reserve(samples);
    candidates_.reserve(samples);
  }
  // Verifies (and, with refine, refines R and t in place). Reuses internal buffers (no allocation once warm).
  VerifyResult verify(const SampleSet& samples, const ModelGeometry& geometry, Mat3& R, Vec3& t, bool refine);
  // verify() with refine, then a line search along `free_dir` (unit, scene frame), a translation direction
  // the matched planes left open and ICP cannot fix (point-to-plane terms do not constrain it): the pose
  // slides to the offset the points fit best with at least as many inliers (VerifyParams::slide_*), when that
  // fits better by more than slide_gain; then finer steps on `samples` (slide_fine_mm) keep any gain.
  // The search runs on `search` (the coarse samples: cheaper), the result is verify()'s on `samples`.
  VerifyResult verify_sliding(const SampleSet& samples, const SampleSet& search,
                              const ModelGeometry& geometry, Mat3& R, Vec3& t, const Vec3& free_dir);
  // evaluate()'s result for the pose as it is (no refinement) when its confidence exceeds `floor`; otherwise
  // a result whose confidence is 0, possibly after only part of the samples (it stops once the samples left
  // could not lift the confidence above `floor`, each of them an inlier at best). The cell lists below are
  // then partial.
  VerifyResult check_above(const SampleSet& samples, const ModelGeometry& geometry, const Mat3& R,
                           const Vec3& t, double floor);
  // Cell indices of the inliers of the last verify() call (for colouring the cloud by object).
  const std::vector<std::uint32_t>& inlier_cells() const { return inlier_cells_; }
  // Cell indices of the measured points in front of the predicted surface (occluded) in the last evaluation.
  const std::vector<std::uint32_t>& occluded_cells() const { return occluded_cells_; }
  const VerifyParams& params() const { return params_; }

 private:
  // floor >= 0: check_above()'s early stop.
  VerifyResult evaluate(const SampleSet& samples, const ModelGeometry& g, const Mat3& R, const Vec3& t,
                        double floor = -1.0);
  VerifyParams params_;
  std::vector<std::uint32_t> candidates_;  // samples whose rays pass the posed model's bounding sphere
  std::vector<std::uint32_t> inlier_cells_, occluded_cells_;
  std::vector<std::uint32_t> inlier_sample_;
  std::vector<std::int32_t> inlier_face_;
  std::vector<std::uint32_t> front_;  // front_faces() of the current pose's viewpoint
  ClipFaces clip_;                    // ... or its clip_faces() (convex models)
};

}  // namespace fs::host::rec
