#pragma once
// Support beyond the table (recognizer, beyond the thesis): a solid resting on another one hides the face it
// rests on, so the support test (support_factor) finds no measured point under its lowest point. It stands
// when it rests on an object accepted in the same decision (accept.cpp), measured against convex solids
// (ModelGeometry::depth_inside). (A measured surface at the height of its lowest point beside it is no proof:
// the rim of a larger solid whose top part a smaller model fits looks the same.)
#include "host/recognize/verify.hpp"

namespace fs::host::rec {

struct PosedModel {
  const ModelGeometry* geometry = nullptr;
  Mat3 R = Mat3::Identity();
  Vec3 t = Vec3::Zero();
};

// Model `upper` rests on a convex `lower`: lower's centre is below upper's and a point of upper's surface
// near its lowest point (upper_lowest above the table; ModelGeometry::any_surface_sample, radius / 12 apart)
// lies on lower's surface (at most tol_mm outside it, or inside it).
bool rests_on(const PosedModel& upper, double upper_lowest, const PosedModel& lower, const Plane& table,
              double tol_mm);

}  // namespace fs::host::rec
