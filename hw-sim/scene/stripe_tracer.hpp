#pragma once
// Per image row, the exact stripe point of a laser plane (see stripe_truth.hpp). Work: the laser plane is cut
// with every face polygon and with the table into 3D segments; each segment is split into pieces whose image
// rows are monotonic, and for every image row a piece crosses, the point projecting exactly onto that row is
// solved (bracketed secant on the distorted projection). Each such point is kept if it faces both the mirror
// and the camera and neither the path from the mirror nor the path to the camera is blocked.
// Memory is allocated in the constructor; trace() does not allocate.
#include <span>
#include <vector>

#include "hw-sim/scene/ray_cast.hpp"
#include "hw-sim/scene/stripe_truth.hpp"

namespace fs::sim {

class StripeTracer {
 public:
  explicit StripeTracer(const Scene& scene);

  // rows.size() must be the camera height. Fills every row (invalid rows: object = -1).
  void trace(const Plane& laser_plane, std::span<StripeSample> rows);
  void trace_mirror_angle(double mirror_angle_rad, std::span<StripeSample> rows) {
    trace(scene_->calibration.laser.plane_at_mirror_angle(mirror_angle_rad), rows);
  }

  const SceneRayCaster& caster() const { return caster_; }
  const Scene& scene() const { return *scene_; }
  // The light source: the point where the laser leaves the mirror (the axis point).
  Vec3 laser_origin() const { return scene_->calibration.laser.axis_point; }

 private:
  struct Segment {
    Vec3 a, b;
    Vec3 normal;
    std::int32_t object, face;
  };
  void add_face_segments(const Plane& laser, std::size_t oi);
  void add_table_segment(const Plane& laser);
  void solve_segment(const Segment& s, std::span<StripeSample> rows);
  void consider(const Segment& s, const Vec3& x, double u, std::uint32_t row, std::span<StripeSample> rows);

  const Scene* scene_;
  SceneRayCaster caster_;
  std::vector<Segment> segments_;
  std::vector<double> crossings_;      // scratch: polygon edge crossings along the cut line
  std::vector<Vec3> table_footprint_;  // camera view rays hitting the table (precomputed)
};

}  // namespace fs::sim
