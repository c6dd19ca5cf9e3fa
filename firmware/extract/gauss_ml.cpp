#include "firmware/extract/gauss_ml.hpp"

#include <algorithm>
#include <cmath>

#include "firmware/extract/fast_log.hpp"
#include "firmware/extract/row_scan.hpp"

namespace fs::fw::detail {
namespace {

// Solves the symmetric 3x3 system [m0 m1 m2; m1 m2 m3; m2 m3 m4] z = r for z[1], z[2] (Cramer's rule; the
// moment matrix of 1, x, x^2). Returns false when singular.
bool solve_moments(const double m[5], const double r[3], double& z1, double& z2) {
  const double c00 = m[2] * m[4] - m[3] * m[3], c01 = m[1] * m[4] - m[3] * m[2],
               c02 = m[1] * m[3] - m[2] * m[2];
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
                     double& centre, bool intensity_step) {
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
  if (!intensity_step) {
    centre = ic + u0;
    return true;
  }
  const int ka = std::max(0, static_cast<int>(std::floor(ic + u0 - 3.0 * s)));
  const int kb = std::min(n - 1, static_cast<int>(std::ceil(ic + u0 + 3.0 * s)));
  const float af = static_cast<float>(a), bf = static_cast<float>(b), cf = static_cast<float>(c);
  const float r2 = static_cast<float>(noise.read * noise.read + 1.0 / 12.0);
  const float q2 = static_cast<float>(noise.shot * noise.shot),
              p2 = static_cast<float>(noise.speckle * noise.speckle);
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

namespace {

// The batched fit (gauss_ml.hpp) on generic vectors of W lanes, native width: W = 8 with AVX2, W = 4 on
// SSE2 / NEON (two groups of 4 lanes side by side per batch; wider generic vectors lower to poor code there).
// Float lanes for the per-sample work, double lanes for the solves. Masks instead of branches; everything
// outside a lane's samples adds exact zeros. Comparisons give 0 / -1 lanes; `m & kOne` turns such a mask into
// 0.0f / 1.0f.
using f64x4 = double __attribute__((vector_size(32)));
using i64x4 = std::int64_t __attribute__((vector_size(32)));
using f64x8 = double __attribute__((vector_size(64)));
using i64x8 = std::int64_t __attribute__((vector_size(64)));
constexpr std::int32_t kOne = 0x3f800000;  // the bits of 1.0f

template <int W>
struct Lanes;
template <>
struct Lanes<4> {
  using F = f32x4;
  using I = i32x4;
  using D = f64x4;
  using DI = i64x4;
};
template <>
struct Lanes<8> {
  using F = f32x8;
  using I = i32x8;
  using D = f64x8;
  using DI = i64x8;
};

// x = -kBatchHalf .. kBatchHalf - 1 as int, float and float x^2 (all exact), indexed by kBatchHalf + x: a
// broadcast from memory is a load, where the conversion and product of a loop counter are vector-unit work.
constexpr auto kXTables = [] {
  struct {
    std::int32_t i[2 * kBatchHalf];
    float f[2 * kBatchHalf], f2[2 * kBatchHalf];
  } t{};
  for (int k = 0; k < 2 * kBatchHalf; ++k) {
    t.i[k] = k - kBatchHalf;
    t.f[k] = static_cast<float>(k - kBatchHalf);
    t.f2[k] = t.f[k] * t.f[k];
  }
  return t;
}();
constexpr auto& kXi = kXTables.i;
constexpr auto& kX = kXTables.f;
constexpr auto& kX2 = kXTables.f2;

template <typename V>
inline V load(const void* p) {
  V v;
  __builtin_memcpy(&v, p, sizeof v);
  return v;
}
// True when every lane of the 0 / -1 mask m is 0 (8 lanes or-ed down to 4 in a vector register first: one
// extract and or, where each 64-bit piece took a move to a general register).
inline bool none(i32x4 m) {
  std::uint64_t parts[2];
  __builtin_memcpy(parts, &m, sizeof parts);
  return !(parts[0] | parts[1]);
}
inline bool none(i32x8 m) {
  i32x4 half[2];
  __builtin_memcpy(half, &m, sizeof half);
  return none(half[0] | half[1]);
}
template <typename D>
inline D vabs(D v) {
  return v < 0.0 ? -v : v;
}
template <typename D>
inline D vmax(D a, D b) {
  return a < b ? b : a;
}  // std::max's order

// Masks of double lanes as doubles whose bits are all ones / zero (kAll / D{}), made by `condition ? all : 0`
// with the comparison used only there, and applied with bit operations (pick): GCC 12 lowers a comparison of
// 8 doubles whose 0 / -1 result is kept as a value (or used twice) lane by lane even with AVX-512; this way
// it stays vector code. Same bits as the plain selects.
template <typename D, typename DI>
inline D pick(D m, D x, D y) {
  const DI mi = std::bit_cast<DI>(m);
  return std::bit_cast<D>((std::bit_cast<DI>(x) & mi) | (std::bit_cast<DI>(y) & ~mi));
}
template <typename D, typename DI>
inline D both(D a, D b) {
  return std::bit_cast<D>(std::bit_cast<DI>(a) & std::bit_cast<DI>(b));
}

// Cramer's rule for z1, z2 of the moment system (solve_moments), all lanes; `regular` = not singular (a
// mask).
template <int W>
inline void solve_lanes(const typename Lanes<W>::F (&acc)[8], typename Lanes<W>::D& z1,
                        typename Lanes<W>::D& z2, typename Lanes<W>::D& regular) {
  using D = typename Lanes<W>::D;
  using DI = typename Lanes<W>::DI;
  const D all = std::bit_cast<D>(DI{} - 1);
  D m[8];
  for (int q = 0; q < 8; ++q) m[q] = __builtin_convertvector(acc[q], D);
  const D c00 = m[2] * m[4] - m[3] * m[3], c01 = m[1] * m[4] - m[3] * m[2], c02 = m[1] * m[3] - m[2] * m[2];
  const D det = m[0] * c00 - m[1] * c01 + m[2] * c02;
  regular = vabs(det) > 1e-12 * vmax(D{} + 1.0, m[0] * m[2] * m[4]) ? all : D{};
  const D inv = 1.0 / pick<D, DI>(regular, det, D{} + 1.0);  // one division for both
  z1 = (m[0] * (m[6] * m[4] - m[3] * m[7]) - m[5] * c01 + m[2] * (m[1] * m[7] - m[6] * m[2])) * inv;
  z2 = (m[0] * (m[2] * m[7] - m[6] * m[3]) - m[1] * (m[1] * m[7] - m[6] * m[2]) + m[5] * c02) * inv;
}

// Lanes [0, G W) of the batch as G groups of W lanes (group h: lanes [h W, h W + W)), the groups side by side
// at every step: the fit is a chain of dependent steps (walk, solve, sums, solve), and two groups give the
// core two independent chains (the portable build: two groups of 4 lanes). A walk or a sum loop runs over
// the union of the groups' ranges; a group's lanes outside their own add exact zeros, as any lane's do
// outside its window, so every lane's result is the one of its group alone, bit for bit.
template <int W, int G>
[[gnu::always_inline]] inline void batch_fit_lanes(GaussMlBatch& b, const SensorNoise& noise) {
  using F = typename Lanes<W>::F;
  using I = typename Lanes<W>::I;
  using D = typename Lanes<W>::D;
  using DI = typename Lanes<W>::DI;
  constexpr int C = kBatchHalf;
  const auto one = [](I m) { return std::bit_cast<F>(m & kOne); };
  const D all = std::bit_cast<D>(DI{} - 1);
  const auto pk = [](D m, D x, D y) { return pick<D, DI>(m, x, y); };
  const auto both2 = [](D a, D b) { return both<D, DI>(a, b); };
  F fl[G], cl[G];
  I xa1[G], xb1[G];  // x >= xa as x > xa - 1, x <= xb as xb + 1 > x
  // 1. Unweighted log-parabola over the contiguous samples above 10 % of the contrast: the walks out of the
  // peak are lane masks (alive while every sample so far was above the floor and inside the window).
  F a[G][8] = {};  // per lane: 1, x, x^2, x^3, x^4, ln y, x ln y, x^2 ln y
  for (int h = 0; h < G; ++h) {
    const int g = h * W;
    const D contrast = load<D>(b.contrast + g);
    fl[h] = __builtin_convertvector(vmax(0.1 * contrast, D{} + 1e-3), F);
    cl[h] = __builtin_convertvector(load<D>(b.clip + g), F);
    xa1[h] = load<I>(b.xa + g) - 1;
    xb1[h] = load<I>(b.xb + g) + 1;
    const F v = load<F>(&b.y[C][g]);  // x = 0, the peak sample
    const F w = one((v > fl[h]) & (v < cl[h]));
    a[h][0] += w;
    a[h][5] += w * fast_lnf(v < fl[h] ? fl[h] : v);
  }
  for (int dir = 1; dir >= -1; dir -= 2) {
    I alive[G];
    for (int h = 0; h < G; ++h) alive[h] = I{} - 1;
    for (int d = 1; d < C; ++d) {
      const int x = dir * d;
      const float xf = kX[C + x], x2 = kX2[C + x];
      F v[G];
      I some{};
      for (int h = 0; h < G; ++h) {
        v[h] = load<F>(&b.y[C + x][h * W]);
        alive[h] &= (I{} + kXi[C + x] > xa1[h]) & (xb1[h] > I{} + kXi[C + x]) & (v[h] > fl[h]);
        some |= alive[h];
      }
      if (none(some)) break;
      for (int h = 0; h < G; ++h) {
        const F w = one(alive[h] & (v[h] < cl[h]));
        const F ly = w * fast_lnf(v[h] < fl[h] ? fl[h] : v[h]);
        a[h][0] += w;
        a[h][1] += w * xf;
        a[h][2] += w * x2;
        a[h][3] += w * x2 * xf;
        a[h][4] += w * x2 * x2;
        a[h][5] += ly;
        a[h][6] += ly * xf;
        a[h][7] += ly * x2;
      }
    }
  }
  D regular[G], bs[G], cs[G], u0[G];
  I ok[G], ka1[G], kb1[G];
  F af[G], bf[G], cf[G];
  std::int32_t xmin = C, xmax = -C;
  for (int h = 0; h < G; ++h) {
    D bb, cc;
    solve_lanes<W>(a[h], bb, cc, regular[h]);
    const D m0 = __builtin_convertvector(a[h][0], D), m1 = __builtin_convertvector(a[h][1], D),
            m2 = __builtin_convertvector(a[h][2], D), r0 = __builtin_convertvector(a[h][5], D);
    D good = both2(both2(m0 >= 3.0 ? all : D{}, regular[h]), cc < 0.0 ? all : D{});
    bs[h] = pk(good, bb, D{});  // failed lanes: a harmless model, exp(0)
    cs[h] = pk(good, cc, D{} - 1.0);
    const D ic = 1.0 / cs[h];  // one division for u0, sigma^2 and ln_peak
    u0[h] = -0.5 * bs[h] * ic;
    good = both2(good, vabs(u0[h]) <= 2.0 ? all : D{});
    const D ai = (r0 - bs[h] * m1 - cs[h] * m2) / vmax(m0, D{} + 1.0);
    D sd = -0.5 * ic;
    for (int j = 0; j < W; ++j) sd[j] = __builtin_sqrt(sd[j]);  // > 0; no errno (-fno-math-errno): vsqrtpd
    const D ln_peak = ai - 0.25 * bs[h] * bs[h] * ic;
    good = both2(good, sd >= 0.25 ? all : D{});
    good = both2(good, ln_peak <= 30.0 ? all : D{});
    good = both2(good, ln_peak >= -10.0 ? all : D{});
    // Window |x - u| <= 3 sigma inside the lane's samples (clamped first: the int conversions stay defined).
    D tlo = u0[h] - 3.0 * sd, thi = u0[h] + 3.0 * sd;
    tlo = tlo < -1.0 * C ? -1.0 * C : tlo > 1.0 * C ? 1.0 * C : tlo;
    thi = thi < -1.0 * C ? -1.0 * C : thi > 1.0 * C ? 1.0 * C : thi;
    I flo = __builtin_convertvector(tlo, I), chi = __builtin_convertvector(thi, I);
    // floor: -1 where truncation went up; ceil: +1
    flo += __builtin_convertvector(std::bit_cast<DI>(tlo < __builtin_convertvector(flo, D) ? all : D{}), I);
    chi -= __builtin_convertvector(std::bit_cast<DI>(thi > __builtin_convertvector(chi, D) ? all : D{}), I);
    ok[h] = __builtin_convertvector(std::bit_cast<DI>(good), I);
    const I xa = xa1[h] + 1, xb = xb1[h] - 1;
    const I ka = ok[h] ? (xa < flo ? flo : xa) : 1;
    const I kb = ok[h] ? (xb < chi ? xb : chi) : 0;
    ka1[h] = ka - 1;  // x >= ka as x > ka - 1, x <= kb as kb + 1 > x: one compare each
    kb1[h] = kb + 1;
    af[h] = __builtin_convertvector(pk(good, ai, D{}), F);
    bf[h] = __builtin_convertvector(pk(good, bs[h], D{}), F);  // a failed lane's model: exp(0), inert
    cf[h] = __builtin_convertvector(pk(good, cs[h], D{}), F);
    for (int j = 0; j < W; ++j) {
      xmin = std::min(xmin, ka[j]);
      xmax = std::max(xmax, kb[j]);
    }
  }
  if (!b.intensity_step) {  // GaussLog: the log-parabola's centre
    for (int h = 0; h < G; ++h) {
      __builtin_memcpy(b.centre + h * W, &u0[h], sizeof u0[h]);
      const I ok01 = ok[h] & 1;
      __builtin_memcpy(b.ok + h * W, &ok01, sizeof ok01);
    }
    return;
  }
  // 2. One Gauss-Newton step in the intensity domain, weights 1 / var(model) (see gauss_ml_centre), over the
  // union of the lanes' windows, masked outside each lane's. The model S(x) = exp(a + b x + c x^2) by
  // recurrence outward from x = 0: S(x + 1) = S(x) R(x), R(x + 1) = R(x) exp(2c) (and the same leftward),
  // seeded by four fast_expf whose arguments lie in its domain (|u0| <= 2, c >= -8, ln_peak in [-10, 30]).
  // Within a lane's window S >= e^-50 (see gauss_ml_centre); past it S only falls, and the floor of 1e-30
  // keeps it out of the denormals (slow) without touching any value that is used. Relative error of S after
  // the <= 16 steps: < 1e-5 (against 12 % speckle).
  const float rr = static_cast<float>(noise.read * noise.read + 1.0 / 12.0);
  const float q2 = static_cast<float>(noise.shot * noise.shot),
              p2 = static_cast<float>(noise.speckle * noise.speckle);
  // Each direction its own loop and set of sums.
  F gr[G][8] = {}, gl[G][8] = {};  // per lane: w, w x, w x^2, w x^3, w x^4, we, we x, we x^2
  const auto add = [&](F(&gs)[8], int h, int x, F S) {
    const float xf = kX[C + x], x2 = kX2[C + x];  // loads, not conversions
    const I xv = I{} + kXi[C + x];
    const F v = load<F>(&b.y[C + x][h * W]);
    // S where the sample is in (S > 0 and finite: the same bits as 1.0f * S), +0 = 0.0f * S elsewhere.
    const F mS = std::bit_cast<F>((xv > ka1[h]) & (kb1[h] > xv) & (v < cl[h]) & std::bit_cast<I>(S));
    const F sv = mS / (rr + S * (q2 + p2 * S));
    const F w = S * sv, we = (v - S) * sv;
    gs[0] += w;
    gs[1] += w * xf;
    gs[2] += w * x2;
    gs[3] += w * x2 * xf;
    gs[4] += w * x2 * x2;
    gs[5] += we;
    gs[6] += we * xf;
    gs[7] += we * x2;
  };
  const F tiny = F{} + 1e-30f;
  // max(v, tiny) on the bits as integers: the same as v < tiny ? tiny : v for every v but a NaN with the sign
  // set (a negative v or -0 gives tiny both ways), and v here is a product of positive finite floats; one
  // integer max where the float select was a compare and a blend, on the recurrences' chains.
  const I tiny_bits = std::bit_cast<I>(tiny);
  const auto floor_at = [&](F v) {
    const I vb = std::bit_cast<I>(v);
    return std::bit_cast<F>(vb < tiny_bits ? tiny_bits : vb);
  };
  F Sr[G], Rr[G], Sl[G], Ll[G], Q[G];
  for (int h = 0; h < G; ++h) {
    const F S0 = fast_expf(af[h]);
    Q[h] = fast_expf(cf[h] + cf[h]);
    Sr[h] = S0;  // rightward: S(x), S(x + 1) / S(x) at x = 0
    Rr[h] = fast_expf(bf[h] + cf[h]);
    const F L0 = fast_expf(cf[h] - bf[h]);  // leftward: S(x - 1) / S(x) at x = 0
    Sl[h] = floor_at(S0 * L0);
    Ll[h] = floor_at(L0 * Q[h]);
  }
  const int nr = xmax + 1, nl = -xmin;  // x = 0 .. xmax and x = -1 .. xmin
  for (int d = 0; d < nr; ++d) {
    for (int h = 0; h < G; ++h) {
      add(gr[h], h, d, Sr[h]);
      Sr[h] = floor_at(Sr[h] * Rr[h]);
      Rr[h] = floor_at(Rr[h] * Q[h]);
    }
  }
  for (int d = 0; d < nl; ++d) {
    for (int h = 0; h < G; ++h) {
      add(gl[h], h, -1 - d, Sl[h]);
      Sl[h] = floor_at(Sl[h] * Ll[h]);
      Ll[h] = floor_at(Ll[h] * Q[h]);
    }
  }
  for (int h = 0; h < G; ++h) {
    const int g = h * W;
    F gs[8];
    for (int q = 0; q < 8; ++q) gs[q] = gr[h][q] + gl[h][q];
    D db, dc, reg;
    solve_lanes<W>(gs, db, dc, reg);
    const D b1 = bs[h] + db, c1 = cs[h] + dc;
    const D curved = c1 < 0.0 ? all : D{};
    const D u1 = -b1 / (2.0 * pk(curved, c1, D{} - 1.0));
    const D take = both2(both2(reg, curved), vabs(u1 - u0[h]) <= 1.0 ? all : D{});
    const D centre = pk(take, u1, u0[h]);
    __builtin_memcpy(b.centre + g, &centre, sizeof centre);
    const I ok01 = ok[h] & 1;
    __builtin_memcpy(b.ok + g, &ok01, sizeof ok01);
  }
}

[[gnu::always_inline]] inline void batch_fit(GaussMlBatch& b, const SensorNoise& noise) {
  static_assert(kBatch == 8, "two groups of 4 lanes");
  batch_fit_lanes<4, 2>(b, noise);
}

#if defined(__x86_64__)
static_assert(kBatch == 8, "one AVX2 vector of lanes");
__attribute__((target("avx2"))) void batch_fit_avx2(GaussMlBatch& b, const SensorNoise& noise) {
  batch_fit_lanes<8, 1>(b, noise);
}
// The same 8 lanes (256-bit vectors) with AVX-512VL's 32 vector registers: the AVX2 build spills its
// accumulators and constants to the stack; this one does not (bench_extract --benchmark_filter=GaussMlBatch).
__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"))) void batch_fit_avx512(
    GaussMlBatch& b, const SensorNoise& noise) {
  batch_fit_lanes<8, 1>(b, noise);
}
#endif

}  // namespace

void gauss_ml_centre_batch_portable(GaussMlBatch& b, const SensorNoise& noise) { batch_fit(b, noise); }

bool gauss_ml_centre_batch_avx2([[maybe_unused]] GaussMlBatch& b, [[maybe_unused]] const SensorNoise& noise) {
#if defined(__x86_64__)
  if (cpu_has_avx2()) {
    batch_fit_avx2(b, noise);
    return true;
  }
#endif
  return false;
}

const char* gauss_ml_batch_isa() {
  return cpu_has_avx512vl() ? "avx512vl" : cpu_has_avx2() ? "avx2" : "portable";
}

void gauss_ml_centre_batch(GaussMlBatch& b, const SensorNoise& noise) {
#if defined(__x86_64__)
  if (cpu_has_avx512vl()) {
    batch_fit_avx512(b, noise);
    return;
  }
  if (cpu_has_avx2()) {
    batch_fit_avx2(b, noise);
    return;
  }
#endif
  batch_fit(b, noise);
}

double centre_crb(double u, double s, double A, double background, double full_scale_dn,
                  const SensorNoise& noise) {
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
