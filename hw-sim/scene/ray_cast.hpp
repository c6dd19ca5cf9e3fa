#pragma once
// Ray casting against a scene: objects' polygons (with per-object bounding boxes) and the table plane.
#include <cstdint>
#include <vector>

#include "hw-sim/scene/scene.hpp"

namespace fs::sim {

struct RayHit {
  double s = 0.0;  // distance along the (unit) direction
  Vec3 point = Vec3::Zero();
  Vec3 normal = Vec3::UnitZ();  // outward normal of the surface hit
  std::int32_t object = -1;     // 0 = table, i + 1 = object i
  std::int32_t face = -1;
};

class SceneRayCaster {
 public:
  explicit SceneRayCaster(const Scene& scene);

  // First surface along origin + s * dir, 0 < s < s_max (dir must be unit length). Allocation-free.
  bool cast(const Vec3& origin, const Vec3& dir, double s_max, RayHit& hit) const;
  // True when some surface lies strictly between a and b (ends excluded by `eps` mm).
  bool blocked(const Vec3& a, const Vec3& b, double eps = 1e-3) const;

  // Polygon test for object `object_index` (0-based), face `face`: is x (on the face plane) inside?
  bool inside_face(std::size_t object_index, std::size_t face, const Vec3& x) const;

  const Scene& scene() const { return *scene_; }

 private:
  struct Face {
    Plane plane;
    int drop_axis = 2;                   // coordinate dropped for the 2D point-in-polygon test
    std::uint32_t first = 0, count = 0;  // range in poly2_
  };
  struct Object {
    Eigen::AlignedBox3d bounds;
    std::uint32_t first_face = 0, face_count = 0;
  };
  bool hit_object(const Object& o, std::size_t oi, const Vec3& origin, const Vec3& dir, double s_max,
                  RayHit& hit) const;
  bool inside(const Face& f, const Vec3& x) const;

  const Scene* scene_;
  std::vector<Object> objects_;
  std::vector<Face> faces_;
  std::vector<Vec2> poly2_;
};

}  // namespace fs::sim
