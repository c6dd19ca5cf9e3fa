#include "firmware/extract/along_stripe.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace fs::fw {
namespace {

using detail::kMaxStepPx;

// Chi-square 99 % quantiles for 1..13 degrees of freedom (a window of up to 15 rows minus the line's 2).
constexpr double kChi2_99[14] = {0.0, 6.635, 9.210, 11.345, 13.277, 15.086, 16.812, 18.475,
                                 20.090, 21.666, 23.209, 24.725, 26.217, 27.688};
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

double along_stripe_sigma(std::span<const msg::StripePoint> pts) {
  constexpr int kBins = 512;
  constexpr double kBin = 0.002;  // px
  std::uint32_t hist[kBins] = {};
  std::uint32_t count = 0;
  for (std::size_t j = 1; j + 1 < pts.size(); ++j) {
    if (!joined(pts[j - 1], pts[j]) || !joined(pts[j], pts[j + 1])) continue;
    const double d2 = std::abs(static_cast<double>(pts[j - 1].col) - 2.0 * pts[j].col + pts[j + 1].col);
    ++hist[std::min(kBins - 1, static_cast<int>(d2 / kBin))];
    ++count;
  }
  if (count < 16) return 0.0;
  const double half = 0.5 * count;
  double below = 0.0;
  int b = 0;
  while (b < kBins - 1 && below + hist[b] < half) below += hist[b++];
  const double median = (b + (hist[b] ? (half - below) / hist[b] : 0.5)) * kBin;  // interpolated in its bin
  return 1.4826 * median / std::sqrt(6.0);  // MAD -> sigma of d2, / sqrt(6) -> one row's
}

void refine_along_stripe(std::span<msg::StripePoint> pts, std::uint32_t rows, double sigma) {
  if (rows < 3 || pts.size() < 3 || !(sigma > 0.0)) return;
  const int h = static_cast<int>(std::min(rows, kAlongStripeMaxRows) / 2);
  constexpr int kRing = 16;  // > h: the original centres of the rows already refined
  static_assert(kRing > static_cast<int>(kAlongStripeMaxRows / 2));
  float orig[kRing];
  const double s2 = sigma * sigma;
  struct {  // the full window's constants (x = -h .. h; halves x = -h .. 0 and 0 .. h)
    double inv_n, inv_sxx, mean_half, inv_dxx_half, chi2_full, slope_limit;
  } k{};
  k.inv_n = 1.0 / (2 * h + 1);
  k.inv_sxx = 3.0 / (h * (h + 1.0) * (2 * h + 1.0));
  k.mean_half = 0.5 * h;
  k.inv_dxx_half = 1.0 / sxx_run(h);
  k.chi2_full = kChi2_99[2 * h - 1];
  k.slope_limit = kSlopeSigmas * std::sqrt(s2 * 2.0 / sxx_run(h));
  const std::size_t n = pts.size();
  int a = 0;               // contiguous rows before i (at most h)
  std::size_t run_end = 0;  // first index after i's run
  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0 && i < run_end) a = std::min(a + 1, h);
    else a = 0;
    if (i >= run_end) {
      run_end = i + 1;
      while (run_end < n && joined(pts[run_end - 1], pts[run_end])) ++run_end;
    }
    const int b = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(h), run_end - 1 - i));
    const float own = pts[i].col;
    orig[i % kRing] = own;
    if (a + b < 2) continue;
    const auto y = [&](int x) {  // the original centre of row i + x, relative to row i's
      const std::size_t j = i + static_cast<std::size_t>(static_cast<std::ptrdiff_t>(x));
      return static_cast<double>(x < 0 ? orig[j % kRing] : pts[j].col) - own;
    };
    Line full;
    bool ok;
    if (a == h && b == h) {  // the common case, a full window: fixed x, the sums' constants precomputed
      double sy = 0, sxy = 0, syy = 0, syl = 0, sxyl = 0;  // the left half x <= 0; the right = all - left + y(0)
      for (int x = -h; x <= h; ++x) {
        const double v = y(x);
        sy += v;
        sxy += x * v;
        syy += v * v;
        if (x <= 0) {
          syl += v;
          sxyl += x * v;
        }
      }
      full.n = 2 * h + 1;
      full.at0 = sy * k.inv_n;
      full.slope = sxy * k.inv_sxx;
      full.ssr = syy - full.at0 * sy - full.slope * sxy;
      full.var0 = k.inv_n;
      const double syr = sy - syl, sxyr = sxy - sxyl;  // x >= 1; row i adds 0 to x y and is in both halves
      const double slope_l = (sxyl - k.mean_half * -1.0 * syl) * k.inv_dxx_half;  // mean x of the left: -h/2
      const double slope_r = (sxyr - k.mean_half * syr) * k.inv_dxx_half;       // right: x = 0..h (v(0) = 0)
      ok = full.ssr <= k.chi2_full * s2 && std::abs(slope_l - slope_r) <= k.slope_limit;
    } else {
      full = fit(y, -a, b);
      ok = explains(full, s2);
      if (ok && a >= 1 && b >= 1) {  // no kink at row i: the halves' slopes agree
        const Line l = fit(y, -a, 0), r = fit(y, 0, b);
        const double sd = std::sqrt(s2 * (1.0 / sxx_run(a) + 1.0 / sxx_run(b)));
        ok = std::abs(l.slope - r.slope) <= kSlopeSigmas * sd;
      }
    }
    Line best = full;
    if (!ok) {
      best = Line{};
      best.var0 = 1.0;  // the row alone
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

}  // namespace fs::fw
