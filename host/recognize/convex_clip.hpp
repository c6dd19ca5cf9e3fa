// The ray clip of verification's hot loop (ModelGeometry::cast_convex): a ray against every face half-space
// of a convex model, four faces at a time. The faces are given as padded columns (structure of arrays): a
// padding face has a zero normal and height -1, which clips nothing.
#pragma once

#include <cstddef>

namespace fs::host::rec {

// Faces are padded to a multiple of this.
inline constexpr std::size_t kClipLanes = 4;

struct ConvexFaces {
  const double* nx;  // unit normals, one column per coordinate
  const double* ny;
  const double* nz;
  const double* h;    // n . origin - offset per face: positive outside its plane
  std::size_t count;  // a multiple of kClipLanes
};

// The ray origin + s dir (s > 0) enters the model through the face of the latest entry and hits it when no
// face lets it out before. Returns that face (distance: its s), or -1 for a miss: the ray parallel to a face
// plane with the origin outside it (grazing), leaving before it enters, or entering nowhere ahead (the origin
// inside, or the ray pointing away). Bit for bit the result of the face-by-face loop it replaces: the same
// divisions, the same comparisons, the first face of the largest entry.
int clip_convex(const ConvexFaces& faces, double dx, double dy, double dz, double& distance);

// The variants clip_convex picks from (the same results; tests run each the CPU has).
int clip_convex_portable(const ConvexFaces& faces, double dx, double dy, double dz, double& distance);
bool clip_convex_has_avx2();
#if defined(__x86_64__)
int clip_convex_avx2(const ConvexFaces& faces, double dx, double dy, double dz, double& distance);
#endif

}  // namespace fs::host::rec
