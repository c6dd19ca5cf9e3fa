#pragma once
// Per-row kernels of the segmenter's normal pass (host/segment/normals.cpp), on a structure-of-arrays copy
// of the organized grid. Branch-free loops written for the auto-vectorizer (compiled with -fno-math-errno
// -fno-trapping-math); NaN coordinates mean "no data" and make every comparison involving them false.
// Internal to host/segment.
#include <cstddef>
#include <cstdint>

namespace fs::host::seg::kernels {

// Continuity bits of a cell toward its 4 grid neighbours (+ a seed flag used inside the normal pass).
inline constexpr std::uint8_t kContL = 1, kContR = 2, kContU = 4, kContD = 8, kContSeed = 16;

struct Viewpoint {
  float x = 0, y = 0, z = 0;
};

// Copies one row of packed xyz points (S: 3 floats per cell) to X/Y/Z (NaN where a coordinate is not finite
// or |c| >= 1e7) and computes the jump threshold^2 (jump_abs + jump_rel * range)^2 and the plane distance
// tolerance dist_abs + dist_rel * range^2 (0 for cells without data). valid[c] = 1 for cells with data.
void soa_row(const float* __restrict S, int w, Viewpoint vp, float jump_abs, float jump_rel, float dist_abs,
             float dist_rel, float* __restrict X, float* __restrict Y, float* __restrict Z,
             float* __restrict J2, float* __restrict DI, std::uint8_t* __restrict valid);

// Normals of cells [c0, c1) of one row from central differences over +-sx cells along the row and +-sy rows
// (row stride W), for cells whose 4 neighbours there have data and are within jump^2 * s^2 (jump^2 at least
// floor2_x along the row, floor2_y across); NaN normal (and 0 area / lengths)
// where that fast path does not apply. All pointers point at the row's first cell. Normal toward the
// viewpoint; AR = |du x dv|, LU = |du|^2, LV = |dv|^2.
void normals_row_fast(const float* __restrict X, const float* __restrict Y, const float* __restrict Z,
                      const float* __restrict J2, float floor2_x, float floor2_y, int c0, int c1, int sx,
                      int sy, std::ptrdiff_t W, Viewpoint vp, float* __restrict NX, float* __restrict NY,
                      float* __restrict NZ, float* __restrict AR, float* __restrict LU, float* __restrict LV);

// Depth continuity of cell i toward cell j: |d|^2 <= jump2, or |d| <= jump_max at more than the jump angle to
// the viewing ray (cos2 = cos^2 of that angle).
inline bool continuous(const float* X, const float* Y, const float* Z, float jump2, std::ptrdiff_t i,
                       std::ptrdiff_t j, Viewpoint vp, float jmax2, float cos2) {
  const float dx = X[j] - X[i], dy = Y[j] - Y[i], dz = Z[j] - Z[i];
  const float dd = dx * dx + dy * dy + dz * dz;
  const float rx = X[i] - vp.x, ry = Y[i] - vp.y, rz = Z[i] - vp.z;
  const float cr = rx * dx + ry * dy + rz * dz;
  const float r2 = rx * rx + ry * ry + rz * rz;
  return (int(dd <= jump2) | (int(dd <= jmax2) & int(cr * cr < cos2 * dd * r2))) != 0;
}

// Continuity bits of cells [c0, c1) of an inner row (row stride W; 1 <= c0, c1 <= W - 1) plus kContSeed where
// the cell's normal agrees with its 4 neighbours' (dot >= cos_seed) and all 4 are continuous. The jump
// threshold^2 is J2[i], at least floor2_x toward the row's neighbours and floor2_y toward the next rows'.
void cont_seeds_row_fast(const float* __restrict X, const float* __restrict Y, const float* __restrict Z,
                         const float* __restrict J2, float floor2_x, float floor2_y,
                         const float* __restrict NX, const float* __restrict NY, const float* __restrict NZ,
                         int c0, int c1, std::ptrdiff_t W, Viewpoint vp, float jmax2, float cos2,
                         float cos_seed, std::uint8_t* __restrict CT);

// Region finalization (host/segment/regions.cpp): for the cells [c0, c1) of an inner row (row stride W;
// 1 <= c0, c1 <= W - 1), |du|^2 and |dv|^2 of the central differences in LU and LV, and in AR the area
// |du x dv| where the cell's label LB is >= 0 and equal to its 4 neighbours' (-1 elsewhere). X, Y, Z, LB
// point at the row's first cell, AR, LU, LV at a row of their own.
void interior_area_row(const float* __restrict X, const float* __restrict Y, const float* __restrict Z,
                       const std::int32_t* __restrict LB, int c0, int c1, std::ptrdiff_t W,
                       float* __restrict AR, float* __restrict LU, float* __restrict LV);

}  // namespace fs::host::seg::kernels
