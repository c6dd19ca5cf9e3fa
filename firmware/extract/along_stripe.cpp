#include "firmware/extract/along_stripe.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>

#include "firmware/extract/row_scan.hpp"

namespace fs::fw {
namespace {

using detail::kMaxStepPx;

// Chi-square 99 % quantiles for 1..13 degrees of freedom (a window of up to 15 rows minus the line's 2).
constexpr double kChi2_99[14] = {0.0,    6.635,  9.210,  11.345, 13.277, 15.086, 16.812,
                                 18.475, 20.090, 21.666, 23.209, 24.725, 26.217, 27.688};
// Medians of chi-square for 1..13 degrees of freedom (the odd ones are used: windows of 3..15 rows minus 2).
constexpr double kChi2Median[14] = {0.0,     0.45494, 1.38629, 2.36597, 3.35669,  4.35146,  5.34812,
                                    6.34581, 7.34412, 8.34283, 9.34182, 10.34100, 11.34032, 12.33976};
// The two halves' slopes may differ by this many standard deviations of their difference.
constexpr double kSlopeSigmas = 3.0;

bool joined(const msg::StripePoint& a, const msg::StripePoint& b) {  // b is the row after a, one line
  return b.row == a.row + 1 && std::abs(b.col - a.col) <= kMaxStepPx;
}

struct Line {
  double at0 = 0.0, slope = 0.0, ssr = 0.0, var0 = 0.0;  // value and variance (/ sigma^2) at x = 0
  int n = 0;
};

// Least-squares line through (x, y[x]) for x in [xa, xb] (y relative to the row's own centre).
template <typename Y>
Line fit(const Y& y, int xa, int xb) {
  Line l;
  double sx = 0, sxx = 0, sy = 0, sxy = 0, syy = 0;
  for (int x = xa; x <= xb; ++x) {
    const double v = y(x);
    sx += x;
    sxx += x * x;
    sy += v;
    sxy += x * v;
    syy += v * v;
  }
  const double n = xb - xa + 1;
  const double mx = sx / n, dxx = sxx - sx * mx;  // > 0 for n >= 2
  l.n = xb - xa + 1;
  l.slope = (sxy - mx * sy) / dxx;
  l.at0 = sy / n - l.slope * mx;
  l.ssr = std::max(0.0, syy - l.at0 * sy - l.slope * sxy);
  l.var0 = 1.0 / n + mx * mx / dxx;
  return l;
}

// Sum of (x - mean)^2 over m + 1 consecutive x.
constexpr double sxx_run(int m) { return static_cast<double>(m) * (m + 1) * (m + 2) / 12.0; }

bool explains(const Line& l, double s2) { return l.n < 3 || l.ssr <= kChi2_99[std::min(l.n - 2, 13)] * s2; }

}  // namespace

double along_stripe_scale(std::span<const msg::StripePoint> pts, std::uint32_t rows) {
  if (rows < 3) return 0.0;
  const int H = static_cast<int>(std::min(rows, kAlongStripeMaxRows) / 2), w = 2 * H + 1;
  constexpr int kBins = 512;
  constexpr float kInvBin = 1.0f / 0.002f;  // bins of 0.002 px
  // Four histograms taken in turn, summed at the end: neighbouring windows mostly fall into the same bin, and
  // one histogram's increments of it would wait for each other through memory.
  std::uint32_t hist4[4][kBins] = {};
  std::uint32_t count = 0;
  // The line through the window's w points at x = 0 .. 2H: residual sum of squares from the sums of y, x y,
  // y^2 (y relative to the run's first centre), slid along the run one point at a time (one add per sum and
  // point: the sums of a window from scratch would be chains of w adds). Every kStride-th window of a run
  // goes into the median: neighbouring windows share all but one row, so their residuals hardly differ, and
  // one in four keeps the median as well for a quarter of the square roots and histogram updates.
  constexpr int kStride = 4;
  const double inv_w = 1.0 / w, inv_sxx = 1.0 / sxx_run(w - 1), inv_dof = 1.0 / (w - 2);
  double s0 = 0.0, s1 = 0.0, s2 = 0.0, ref = 0.0;
  int len = 0;  // points of the current run so far (the window holds the last min(len, w) of them)
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (i == 0 || !joined(pts[i - 1], pts[i])) {
      len = 0;
      s0 = s1 = s2 = 0.0;
      ref = pts[i].col;
    }
    const double y = pts[i].col - ref;
    if (len < w) {  // filling the first window of the run
      s0 += y;
      s1 += len * y;
      s2 += y * y;
    } else {  // drop the point w back, shift x down by one, add this one at x = 2H
      const double old = pts[i - static_cast<std::size_t>(w)].col - ref;
      s1 += (w - 1) * y + old - s0;
      s0 += y - old;
      s2 += y * y - old * old;
    }
    if (++len < w || (len - w) % kStride != 0) continue;
    const double c = s1 - H * s0;  // sum of (x - H) y
    const double ssr = std::max(0.0, s2 - s0 * s0 * inv_w - c * c * inv_sxx);
    const float sd = std::sqrt(static_cast<float>(ssr * inv_dof));
    // >= 0; a NaN or inf (not from extract_frame's points) goes to the last bin
    const float bin = sd * kInvBin;
    ++hist4[count & 3][bin < static_cast<float>(kBins - 1) ? static_cast<int>(bin) : kBins - 1];
    ++count;
  }
  if (count < 4) return 0.0;
  std::uint32_t hist[kBins];
  for (int b = 0; b < kBins; ++b) hist[b] = hist4[0][b] + hist4[1][b] + hist4[2][b] + hist4[3][b];
  const double half = 0.5 * count;
  double below = 0.0;
  int b = 0;
  while (b < kBins - 1 && below + hist[b] < half) below += hist[b++];
  const double median = (b + (hist[b] ? (half - below) / hist[b] : 0.5)) * 0.002;  // interpolated in its bin
  // For independent Gaussian errors ssr / sigma^2 is chi-square with k = w - 2 degrees of freedom.
  return median / std::sqrt(kChi2Median[w - 2] / (w - 2));
}

namespace {

// refine_along_stripe for a window of 2H + 1 rows, kChunk points at a time: first the full-window fit of
// every point of the chunk (a fixed-trip-count float loop over the points: vectorized), then the points in
// order, each taking that fit when its window is whole and explained, else the rows it has (near a run's end,
// at a corner or step: the generic fits).
constexpr int kChunk = 64;

template <int H>
[[gnu::always_inline]] inline void refine(std::span<msg::StripePoint> pts, double sigma) {
  constexpr int kW = 2 * H + 1;
  const double s2 = sigma * sigma;
  // The full window's constants (x = -H .. H; halves x = -H .. 0 and 0 .. H).
  constexpr float inv_n = 1.0f / kW, inv_sxx = static_cast<float>(3.0 / (H * (H + 1.0) * (2 * H + 1.0)));
  constexpr float mean_half = 0.5f * H, inv_dxx_half = static_cast<float>(1.0 / sxx_run(H));
  const float chi2_full = static_cast<float>(kChi2_99[2 * H - 1] * s2);
  const float slope_limit = static_cast<float>(kSlopeSigmas * std::sqrt(s2 * 2.0 / sxx_run(H)));
  const std::size_t n = pts.size();
  // c[H + j + x] = the original centre of point i0 + j + x (the H before the chunk carried over: refined by
  // now).
  float c[kChunk + 2 * H] = {};
  float at0[kChunk];
  std::int32_t ok[kChunk];
  int a = 0;                // contiguous rows before i (at most H)
  std::size_t run_end = 0;  // first index after i's run
  for (std::size_t i0 = 0; i0 < n; i0 += kChunk) {
    const int m = static_cast<int>(std::min<std::size_t>(kChunk, n - i0));
    for (int x = 0; x < H; ++x) c[x] = c[kChunk + x];  // the previous chunk's last H originals
    for (int j = 0; j < kChunk + H; ++j)
      c[H + j] = i0 + j < n ? pts[i0 + static_cast<std::size_t>(j)].col : 0.0f;
    for (int j = 0; j < kChunk; ++j) {
      const float own = c[H + j];
      float sy = 0, sxy = 0, syy = 0, syl = 0, sxyl = 0;  // l: the left half x <= 0
      for (int x = -H; x <= H; ++x) {
        const float v = c[H + j + x] - own, xf = static_cast<float>(x);
        sy += v;
        sxy += xf * v;
        syy += v * v;
        if (x <= 0) {  // x is a constant of the unrolled loop
          syl += v;
          sxyl += xf * v;
        }
      }
      const float mean = sy * inv_n, slope = sxy * inv_sxx;
      const float ssr = syy - mean * sy - slope * sxy;
      // The right half x = 0 .. H: all minus the left (row i's own value is 0 here, in both halves).
      const float slope_l = (sxyl + mean_half * syl) * inv_dxx_half;  // mean x of the left: -H / 2
      const float slope_r = ((sxy - sxyl) - mean_half * (sy - syl)) * inv_dxx_half;
      const float ds = slope_l - slope_r;
      at0[j] = mean;
      ok[j] = (ssr <= chi2_full) & (ds <= slope_limit) & (ds >= -slope_limit);
    }
    for (int j = 0; j < m; ++j) {
      const std::size_t i = i0 + static_cast<std::size_t>(j);
      if (i > 0 && i < run_end)
        a = std::min(a + 1, H);
      else
        a = 0;
      if (i >= run_end) {
        run_end = i + 1;
        while (run_end < n && joined(pts[run_end - 1], pts[run_end])) ++run_end;
      }
      const int b = static_cast<int>(std::min<std::size_t>(H, run_end - 1 - i));
      if (a + b < 2) continue;
      const float own = c[H + j];
      if (a == H && b == H && ok[j]) {  // the common case
        pts[i].col = own + at0[j];
        continue;
      }
      const auto y = [&](int x) { return static_cast<double>(c[H + j + x]) - own; };  // relative to row i's
      Line best{};
      best.var0 = 1.0;            // the row alone
      if (!(a == H && b == H)) {  // near the end of a run: the rows there
        const Line full = fit(y, -a, b);
        bool fits = explains(full, s2);
        if (fits && a >= 1 && b >= 1) {  // no kink at row i: the halves' slopes agree
          const Line l = fit(y, -a, 0), r = fit(y, 0, b);
          const double sd = std::sqrt(s2 * (1.0 / sxx_run(a) + 1.0 / sxx_run(b)));
          fits = std::abs(l.slope - r.slope) <= kSlopeSigmas * sd;
        }
        if (fits) best = full;
      }
      if (best.n ==
          0) {  // one side of row i, the one explained with the smaller variance; else the row alone
        for (const auto& [xa, xb] : {std::pair{-a, 0}, std::pair{0, b}}) {
          if (xb - xa < 2) continue;
          const Line side = fit(y, xa, xb);
          if (explains(side, s2) && side.var0 < best.var0) best = side;
        }
        if (best.n == 0) continue;
      }
      pts[i].col = static_cast<float>(own + best.at0);
    }
  }
}

// The default window (15 rows, the hot case) compiled for AVX2 as well, chosen at run time: its chunk loop
// runs 8 points a vector instead of SSE2's 4. The same operations in the same order, no FMA: the same bits.
void refine7_portable(std::span<msg::StripePoint> pts, double sigma) { refine<7>(pts, sigma); }
#if defined(__x86_64__)
__attribute__((target("avx2"))) void refine7_avx2(std::span<msg::StripePoint> pts, double sigma) {
  refine<7>(pts, sigma);
}
#endif
void refine7(std::span<msg::StripePoint> pts, double sigma) {
#if defined(__x86_64__)
  if (detail::cpu_has_avx2()) return refine7_avx2(pts, sigma);
#endif
  refine7_portable(pts, sigma);
}

}  // namespace

void detail::refine_along_stripe_portable(std::span<msg::StripePoint> pts, std::uint32_t rows, double sigma) {
  if (rows < 3 || pts.size() < 3 || !(sigma > 0.0)) return;
  if (std::min(rows, kAlongStripeMaxRows) / 2 >= 7) return refine7_portable(pts, sigma);
  refine_along_stripe(pts, rows, sigma);  // the other windows have one build
}

void refine_along_stripe(std::span<msg::StripePoint> pts, std::uint32_t rows, double sigma) {
  if (rows < 3 || pts.size() < 3 || !(sigma > 0.0)) return;
  switch (std::min(rows, kAlongStripeMaxRows) / 2) {
    case 1:
      refine<1>(pts, sigma);
      break;
    case 2:
      refine<2>(pts, sigma);
      break;
    case 3:
      refine<3>(pts, sigma);
      break;
    case 4:
      refine<4>(pts, sigma);
      break;
    case 5:
      refine<5>(pts, sigma);
      break;
    case 6:
      refine<6>(pts, sigma);
      break;
    default:
      refine7(pts, sigma);
      break;
  }
}

}  // namespace fs::fw
