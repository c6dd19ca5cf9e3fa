#include "host/segment/grid_kernels.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace fs::host::seg::kernels {

void soa_row(const float* __restrict S, int w, Viewpoint vp, float jump_abs, float jump_rel, float dist_abs,
             float dist_rel, float* __restrict X, float* __restrict Y, float* __restrict Z,
             float* __restrict J2, float* __restrict DI, std::uint8_t* __restrict valid) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int c = 0; c < w; ++c) {
    const float x = S[3 * c], y = S[3 * c + 1], z = S[3 * c + 2];
    // Points with any non-finite coordinate carry no data (NaN = no data by contract; inf is treated alike).
    const bool ok = (int(std::abs(x) < 1e7f) & int(std::abs(y) < 1e7f) & int(std::abs(z) < 1e7f)) != 0;
    const float dx = x - vp.x, dy = y - vp.y, dz = z - vp.z;
    const float r2 = dx * dx + dy * dy + dz * dz;
    const float jump = jump_abs + (jump_rel != 0.f ? jump_rel * std::sqrt(r2) : 0.f);
    X[c] = ok ? x : nan;
    Y[c] = ok ? y : nan;
    Z[c] = ok ? z : nan;
    J2[c] = ok ? jump * jump : 0.f;
    DI[c] = ok ? dist_abs + dist_rel * r2 : 0.f;
  }
  for (int c = 0; c < w; ++c) valid[c] = X[c] == X[c] ? 1 : 0;
}

void normals_row_fast(const float* __restrict X, const float* __restrict Y, const float* __restrict Z,
                      const float* __restrict J2, float floor2_x, float floor2_y, int c0, int c1, int sx,
                      int sy, std::ptrdiff_t W, Viewpoint vp, float* __restrict NX, float* __restrict NY,
                      float* __restrict NZ, float* __restrict AR, float* __restrict LU,
                      float* __restrict LV) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::ptrdiff_t s = sx, ws = sy * W;
  const float invx = 0.5f / float(sx), invy = 0.5f / float(sy);
  for (int c = c0; c < c1; ++c) {
    const std::ptrdiff_t i = c;
    const float px = X[i], py = Y[i], pz = Z[i];
    const float xl = X[i - s], yl = Y[i - s], zl = Z[i - s];
    const float xr = X[i + s], yr = Y[i + s], zr = Z[i + s];
    const float xu = X[i - ws], yu = Y[i - ws], zu = Z[i - ws];
    const float xd = X[i + ws], yd = Y[i + ws], zd = Z[i + ws];
    const float lim_x = std::max(J2[i], floor2_x) * float(sx * sx),
                lim_y = std::max(J2[i], floor2_y) * float(sy * sy);
    const float dl = (xl - px) * (xl - px) + (yl - py) * (yl - py) + (zl - pz) * (zl - pz);
    const float dr = (xr - px) * (xr - px) + (yr - py) * (yr - py) + (zr - pz) * (zr - pz);
    const float du = (xu - px) * (xu - px) + (yu - py) * (yu - py) + (zu - pz) * (zu - pz);
    const float dd = (xd - px) * (xd - px) + (yd - py) * (yd - py) + (zd - pz) * (zd - pz);
    const float ux = (xr - xl) * invx, uy = (yr - yl) * invx, uz = (zr - zl) * invx;
    const float tx = (xd - xu) * invy, ty = (yd - yu) * invy, tz = (zd - zu) * invy;
    const float cx = uy * tz - uz * ty, cy = uz * tx - ux * tz, cz = ux * ty - uy * tx;
    const float a = std::sqrt(cx * cx + cy * cy + cz * cz);
    const bool ok =
        (int(dl <= lim_x) & int(dr <= lim_x) & int(du <= lim_y) & int(dd <= lim_y) & int(a > 0.f)) != 0;
    const float sgn = (vp.x - px) * cx + (vp.y - py) * cy + (vp.z - pz) * cz < 0.f ? -1.f : 1.f;
    const float ia = sgn / a;
    NX[i] = ok ? cx * ia : nan;
    NY[i] = ok ? cy * ia : nan;
    NZ[i] = ok ? cz * ia : nan;
    AR[i] = ok ? a : 0.f;
    LU[i] = ok ? ux * ux + uy * uy + uz * uz : 0.f;
    LV[i] = ok ? tx * tx + ty * ty + tz * tz : 0.f;
  }
}

void interior_area_row(const float* __restrict X, const float* __restrict Y, const float* __restrict Z,
                       const std::int32_t* __restrict LB, int c0, int c1, std::ptrdiff_t W,
                       float* __restrict AR, float* __restrict LU, float* __restrict LV) {
  for (int c = c0; c < c1; ++c) {
    const std::ptrdiff_t i = c;
    const std::int32_t l = LB[i];
    const std::int32_t other = (LB[i - 1] ^ l) | (LB[i + 1] ^ l) | (LB[i - W] ^ l) | (LB[i + W] ^ l);
    const bool inside = (other | (l >> 31)) == 0;  // l >> 31: -1 for a negative label
    const float ux = 0.5f * (X[i + 1] - X[i - 1]), uy = 0.5f * (Y[i + 1] - Y[i - 1]),
                uz = 0.5f * (Z[i + 1] - Z[i - 1]);
    const float vx = 0.5f * (X[i + W] - X[i - W]), vy = 0.5f * (Y[i + W] - Y[i - W]),
                vz = 0.5f * (Z[i + W] - Z[i - W]);
    const float cx = uy * vz - uz * vy, cy = uz * vx - ux * vz, cz = ux * vy - uy * vx;
    const float a = std::sqrt(cx * cx + cy * cy + cz * cz);
    AR[i] = inside ? a : -1.f;
    LU[i] = ux * ux + uy * uy + uz * uz;
    LV[i] = vx * vx + vy * vy + vz * vz;
  }
}

void cont_seeds_row_fast(const float* __restrict X, const float* __restrict Y, const float* __restrict Z,
                         const float* __restrict J2, float floor2_x, float floor2_y,
                         const float* __restrict NX, const float* __restrict NY, const float* __restrict NZ,
                         int c0, int c1, std::ptrdiff_t W, Viewpoint vp, float jmax2, float cos2,
                         float cos_seed, std::uint8_t* __restrict CT) {
  for (int c = c0; c < c1; ++c) {
    const std::ptrdiff_t i = c;
    const float jx = std::max(J2[i], floor2_x), jy = std::max(J2[i], floor2_y);
    const bool l = continuous(X, Y, Z, jx, i, i - 1, vp, jmax2, cos2);
    const bool r = continuous(X, Y, Z, jx, i, i + 1, vp, jmax2, cos2);
    const bool u = continuous(X, Y, Z, jy, i, i - W, vp, jmax2, cos2);
    const bool d = continuous(X, Y, Z, jy, i, i + W, vp, jmax2, cos2);
    const float nx = NX[i], ny = NY[i], nz = NZ[i];
    const bool seed = (int(NX[i - 1] * nx + NY[i - 1] * ny + NZ[i - 1] * nz >= cos_seed) &
                       int(NX[i + 1] * nx + NY[i + 1] * ny + NZ[i + 1] * nz >= cos_seed) &
                       int(NX[i - W] * nx + NY[i - W] * ny + NZ[i - W] * nz >= cos_seed) &
                       int(NX[i + W] * nx + NY[i + W] * ny + NZ[i + W] * nz >= cos_seed) & int(l) & int(r) &
                       int(u) & int(d)) != 0;
    CT[i] = std::uint8_t((l ? kContL : 0) | (r ? kContR : 0) | (u ? kContU : 0) | (d ? kContD : 0) |
                         (seed ? kContSeed : 0));
  }
}

}  // namespace fs::host::seg::kernels
