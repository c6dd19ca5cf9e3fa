#include "firmware/extract/gauss_ml.hpp"

#include <algorithm>
#include <cmath>

#include "firmware/extract/fast_log.hpp"

namespace fs::fw::detail {
namespace {

// Solves the symmetric 3x3 system [m0 m1 m2; m1 m2 m3; m2 m3 m4] z = r for z[1], z[2] (Cramer's rule; the
// moment matrix of 1, x, x^2). Returns false when singular.
bool solve_moments(const double m[5], const double r[3], double& z1, double& z2) {
  const double c00 = m[2] * m[4] - m[3] * m[3], c01 = m[1] * m[4] - m[3] * m[2], c02 = m[1] * m[3] - m[2] * m[2];
  const double det = m[0] * c00 - m[1] * c01 + m[2] * c02;
  if (!(std::abs(det) > 1e-12 * std::max(1.0, m[0] * m[2] * m[4]))) return false;
  z1 = (m[0] * (r[1] * m[4] - m[3] * r[2]) - r[0] * c01 + m[2] * (m[1] * r[2] - r[1] * m[2])) / det;
  z2 = (m[0] * (m[2] * r[2] - r[1] * m[3]) - m[1] * (m[1] * r[2] - r[1] * m[2]) + r[0] * c02) / det;
  return true;
}

// out[q] = sum over the lanes of acc[q]: lanes added in float across q (8 sums side by side: vectorized, no
// per-element conversions), then 8 conversions.
inline void lane_sums(const float (&acc)[8][kChunk], double (&out)[8]) {
  float s[8] = {};
  for (int j = 0; j < kChunk; ++j)
    for (int q = 0; q < 8; ++q) s[q] += acc[q][j];
  for (int q = 0; q < 8; ++q) out[q] = s[q];
}

}  // namespace

bool gauss_ml_centre(const float* y, int n, int ic, double contrast, double clip, const SensorNoise& noise,
                     double& centre) {
  if (ic < 0 || ic >= n) return false;
  const float clip_f = static_cast<float>(clip);
  // 1. Unweighted log-parabola over the contiguous samples above 10 % of the contrast (x relative to ic).
  const float floor_y = static_cast<float>(std::max(0.1 * contrast, 1e-3));
  int l = ic, r = ic;
  while (l > 0 && y[l - 1] > floor_y) --l;
  while (r + 1 < n && y[r + 1] > floor_y) ++r;
  float acc[8][kChunk] = {};  // per-lane sums: 1, x, x^2, x^3, x^4, ln y, x ln y, x^2 ln y
  for (int k0 = l; k0 <= r; k0 += kChunk) {
    for (int j = 0; j < kChunk; ++j) {
      const int k = k0 + j;
      const float v = y[k];
      const float w = ((k <= r) & (v > floor_y) & (v < clip_f)) ? 1.0f : 0.0f;  // a mask, not a branch
      const float ly = w * fast_lnf(std::max(v, floor_y));
      const float x = static_cast<float>(k - ic), x2 = x * x;
      acc[0][j] += w;
      acc[1][j] += w * x;
      acc[2][j] += w * x2;
      acc[3][j] += w * x2 * x;
      acc[4][j] += w * x2 * x2;
      acc[5][j] += ly;
      acc[6][j] += ly * x;
      acc[7][j] += ly * x2;
    }
  }
  double sums[8];
  lane_sums(acc, sums);
  double b = 0.0, c = 0.0;
  if (sums[0] < 3.0 || !solve_moments(sums, sums + 5, b, c) || !(c < 0.0)) return false;
  const double u0 = -b / (2.0 * c);
  if (!(std::abs(u0) <= 2.0)) return false;
  const double a = (sums[5] - b * sums[1] - c * sums[2]) / sums[0];  // intercept (the first normal equation)

  // 2. One Gauss-Newton step in the intensity domain with weights 1 / var(model). In the log parameters
  // (a, b, c) the Jacobian row is S (1, x, x^2): the update solves the moment system weighted by S^2 / var
  // against the relative residuals (y - S) / S.
  // fast_expf's domain: with sigma >= 0.25 px and the model's peak below e^30, every exponent over the window
  // |x - u| <= 3 sigma + 1 lies in [-50, 30]. Anything else is not a stripe profile: fall back.
  const double s = std::sqrt(-0.5 / c);
  const double ln_peak = a - b * b / (4.0 * c);
  if (!(s >= 0.25) || !(ln_peak <= 30.0) || !(ln_peak >= -10.0)) return false;
  const int ka = std::max(0, static_cast<int>(std::floor(ic + u0 - 3.0 * s)));
  const int kb = std::min(n - 1, static_cast<int>(std::ceil(ic + u0 + 3.0 * s)));
  const float af = static_cast<float>(a), bf = static_cast<float>(b), cf = static_cast<float>(c);
  const float r2 = static_cast<float>(noise.read * noise.read + 1.0 / 12.0);
  const float q2 = static_cast<float>(noise.shot * noise.shot), p2 = static_cast<float>(noise.speckle * noise.speckle);
  float g[8][kChunk] = {};  // per-lane sums: w, w x, w x^2, w x^3, w x^4, we, we x, we x^2
  for (int k0 = ka; k0 <= kb; k0 += kChunk) {
    for (int j = 0; j < kChunk; ++j) {
      const int k = k0 + j;
      const float v = y[k];
      const float m = ((k <= kb) & (v < clip_f)) ? 1.0f : 0.0f;  // a mask, not a branch
      // Lanes past kb are masked out but evaluated at kb (keeps fast_expf in its domain).
      const float x = static_cast<float>(std::min(k, kb) - ic), x2 = x * x;
      const float S = fast_expf(af + bf * x + cf * x2);
      const float sv = m * S / (r2 + S * (q2 + p2 * S));  // S / var: one division
      const float w = S * sv, we = (v - S) * sv;
      g[0][j] += w;
      g[1][j] += w * x;
      g[2][j] += w * x2;
      g[3][j] += w * x2 * x;
      g[4][j] += w * x2 * x2;
      g[5][j] += we;
      g[6][j] += we * x;
      g[7][j] += we * x2;
    }
  }
  double gs[8];
  lane_sums(g, gs);
  centre = ic + u0;
  double db = 0.0, dc = 0.0;
  if (!solve_moments(gs, gs + 5, db, dc)) return true;
  const double b1 = b + db, c1 = c + dc;
  if (!(c1 < 0.0)) return true;
  const double u1 = -b1 / (2.0 * c1);
  if (std::abs(u1 - u0) <= 1.0) centre = ic + u1;
  return true;
}

double centre_crb(double u, double s, double A, double background, double full_scale_dn, const SensorNoise& noise) {
  const double r2 = noise.read * noise.read + 1.0 / 12.0, q2 = noise.shot * noise.shot,
               p2 = noise.speckle * noise.speckle;
  double F[3][3] = {};
  const int i0 = static_cast<int>(std::floor(u - 8.0 * s)), i1 = static_cast<int>(std::ceil(u + 8.0 * s));
  for (int i = i0; i <= i1; ++i) {
    const double x = i - u, e = std::exp(-x * x / (2.0 * s * s)), S = A * e;
    if (background + S >= full_scale_dn) continue;
    const double var = r2 + q2 * S + p2 * S * S, dvar = q2 + 2.0 * p2 * S;
    const double d[3] = {S * x / (s * s), e, S * x * x / (s * s * s)};  // dS / d(u, A, s)
    // Gaussian likelihood with parameter-dependent variance: d_a d_b / var + (dvar/dS)^2 d_a d_b / (2 var^2).
    const double k = 1.0 / var + 0.5 * dvar * dvar / (var * var);
    for (int p = 0; p < 3; ++p)
      for (int q = 0; q < 3; ++q) F[p][q] += k * d[p] * d[q];
  }
  const double det = F[0][0] * (F[1][1] * F[2][2] - F[1][2] * F[2][1]) -
                     F[0][1] * (F[1][0] * F[2][2] - F[1][2] * F[2][0]) +
                     F[0][2] * (F[1][0] * F[2][1] - F[1][1] * F[2][0]);
  if (!(det > 0.0)) return 1e9;
  return (F[1][1] * F[2][2] - F[1][2] * F[2][1]) / det;
}

}  // namespace fs::fw::detail
