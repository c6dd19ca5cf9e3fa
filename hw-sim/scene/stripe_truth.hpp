#pragma once
// What an ideal scanner sees in one image row for one laser plane: the point of the scene that is on the
// laser plane, lit by the laser (first surface from the mirror) and seen by the camera (first surface from
// the camera centre), and that projects (with lens distortion) onto that image row.
#include <cstdint>
#include <limits>

#include "common/calibration.hpp"

namespace fs::sim {

inline constexpr std::int32_t kNoObject = -1;
inline constexpr std::int32_t kTableObject = 0;  // scene object i has id i + 1

struct StripeSample {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  double column = kNaN;             // true sub-pixel stripe centre u (distorted pixel coordinates)
  Vec3 point{kNaN, kNaN, kNaN};     // true 3D point, world mm
  Vec3 normal{kNaN, kNaN, kNaN};    // outward surface normal at the point
  std::int32_t object = kNoObject;  // 0 = table, i + 1 = scene object i, -1 = nothing in this row
  std::int32_t face = -1;           // polygon index in the object's mesh (0 for the table)
  double laser_distance = 0.0;      // mirror -> point, mm
  double camera_distance = 0.0;     // point -> camera centre, mm
  double cos_incidence = 0.0;       // cos(angle between the normal and the direction to the mirror)
  double cos_view = 0.0;            // cos(angle between the normal and the direction to the camera)
  std::uint32_t candidates = 0;  // lit and seen points found in this row (>1: the nearest to the camera wins)

  bool valid() const { return object != kNoObject; }
};

}  // namespace fs::sim
