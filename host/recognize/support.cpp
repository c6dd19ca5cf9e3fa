#include "host/recognize/support.hpp"

namespace fs::host::rec {

namespace {

// The posed model's surface samples (vertices, face centroids and a grid over each face) within tol_mm of its
// lowest point above the table (its resting face, edge or vertex); calls f(world point) for each until f
// returns true; true when one did.
template <class F>
bool any_lowest_point(const PosedModel& p, const Plane& table, double lowest, double tol_mm, F f) {
  return p.geometry->any_surface_sample([&](const Vec3& s) {
    const Vec3 w = p.R * s + p.t;
    return table.signed_distance(w) <= lowest + tol_mm && f(w);
  });
}

}  // namespace

bool rests_on(const PosedModel& upper, double upper_lowest, const PosedModel& lower, const Plane& table,
              double tol_mm) {
  if (!lower.geometry->convex()) return false;
  const Vec3 cu = upper.R * upper.geometry->center() + upper.t;
  const Vec3 cl = lower.R * lower.geometry->center() + lower.t;
  if (table.signed_distance(cl) >= table.signed_distance(cu)) return false;
  const Mat3 Rt = lower.R.transpose();
  return any_lowest_point(upper, table, upper_lowest, tol_mm, [&](const Vec3& v) {
    return lower.geometry->depth_inside(Rt * (v - lower.t)) >= -tol_mm;
  });
}

}  // namespace fs::host::rec
