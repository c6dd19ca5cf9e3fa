#include "firmware/extract/stripe_extractor.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <string>
#include <type_traits>

#include "common/error.hpp"
#include "firmware/extract/along_stripe.hpp"
#include "firmware/extract/gauss_ml.hpp"
#include "firmware/extract/row_lanes.hpp"
#include "firmware/extract/row_masks.hpp"

#if defined(__x86_64__)
#include <cpuid.h>
#endif
#include "firmware/extract/row_scan.hpp"

namespace fs::fw {

const char* to_string(SubpixelMethod m) {
  switch (m) {
    case SubpixelMethod::CentreOfGravity:
      return "cog";
    case SubpixelMethod::Gaussian3:
      return "gauss3";
    case SubpixelMethod::BlaisRioux:
      return "blais-rioux";
    case SubpixelMethod::GaussFit:
      return "gauss-fit";
    case SubpixelMethod::GaussMl:
      return "gauss-ml";
    case SubpixelMethod::GaussLog:
      return "gauss-log";
  }
  return "unknown";
}

SubpixelMethod parse_subpixel_method(const char* text) {
  const std::string t = text ? text : "";
  if (t == "cog") return SubpixelMethod::CentreOfGravity;
  if (t == "gauss3") return SubpixelMethod::Gaussian3;
  if (t == "blais-rioux") return SubpixelMethod::BlaisRioux;
  if (t == "gauss-fit") return SubpixelMethod::GaussFit;
  if (t == "gauss-ml") return SubpixelMethod::GaussMl;
  if (t == "gauss-log") return SubpixelMethod::GaussLog;
  throw Error("unknown sub-pixel method '" + t +
              "' (expected cog, gauss3, blais-rioux, gauss-fit, gauss-ml or gauss-log)");
}

namespace {

using detail::kBlock;

template <typename T>
inline double at(const T* row, std::uint32_t step, std::int64_t i) {
  return static_cast<double>(row[static_cast<std::size_t>(i) * step]);
}

// Index of the first sample equal to the row maximum `mx`.
template <typename T, std::uint32_t Step>
std::uint32_t first_argmax(const T* row, const detail::RowScan<T>& s, T mx) {
  if constexpr (sizeof(T) == 1 && Step == 1) {
    const void* hit = std::memchr(row, mx, s.n);  // libc's vectorized byte search; mx is in the row
    return hit ? static_cast<std::uint32_t>(static_cast<const std::uint8_t*>(hit) - row) : 0;
  } else {
    std::uint32_t b = 0;
    while (b + 1 < s.nblocks && s.block_max(b) != mx) ++b;
    std::uint32_t i = b * kBlock;
    while (i + 1 < s.n && row[static_cast<std::size_t>(i) * Step] != mx) ++i;
    return i;
  }
}

// The methods whose centres the batched fit computes (gauss_ml.hpp: GaussLog is its first step alone).
inline bool fits_in_batch(SubpixelMethod m) {
  return m == SubpixelMethod::GaussMl || m == SubpixelMethod::GaussLog;
}

// A row whose GaussMl centre waits for the batched fit (lane `lane` of the block's GaussMlBatch): what
// finish_row needs besides the batch's result.
struct Deferred {
  std::int64_t lo = 0, hi = 0, ic = 0;
  double bg = 0.0;
};

// The centre of gravity of the support (GaussMl's fallback when no Gaussian fits, e.g. a clipped narrow top).
template <typename T, std::uint32_t Step>
double support_cog(const T* row, std::int64_t lo, std::int64_t hi, std::int64_t ic, double bg) {
  double s = 0.0, sw = 0.0;
  for (std::int64_t i = lo; i <= hi; ++i) {
    const double v = std::max(0.0, at(row, Step, i) - bg);
    s += v;
    sw += v * static_cast<double>(i);
  }
  return s > 0.0 ? sw / s : static_cast<double>(ic);
}

// One row's analysis, in three stages so that extract_frame can run each stage over a block of rows before
// the next (the rows' dependency chains -- divisions, walks, the calls -- then overlap in the CPU instead of
// running one after the other); extract_row runs them back to back. Same code either way, same results.
template <typename T>
struct RowState {
  const T* row = nullptr;
  std::uint32_t n = 0;
  bool active = false;    // still being analysed (false: `r` is final, or the row waits for the batch)
  bool deferred = false;  // waits for the batched GaussMl fit (then `d` holds the rest)
  RowPeak r;
  Deferred d;
  double bg = 0.0, peak = 0.0, contrast = 0.0;
  T mx = 0;
  std::uint32_t imax = 0;
  std::int64_t lo = 0, hi = 0;
  detail::RowScan<T> scan;  // its lane maxima are spent by the double-peak test (detail::max_outside_u8)
};

// Stage 1: the row pass (stage_pass), then background = row mean, peak = row max (stage_level); rows without
// contrast end here. Two steps so that the block's row passes run back to back, not each waiting for the
// division after it.
template <typename T, std::uint32_t Step>
void stage_pass(RowState<T>& st, const T* row, std::uint32_t n) {
  st.row = row;
  st.r = RowPeak{};
  st.active = st.deferred = false;
  st.n = 0;
  if (n < 5) return;
  detail::scan_row<T, Step>(row, n, st.scan);
  st.n = st.scan.n;  // clamps absurd widths
}
template <typename T>
void stage_level(RowState<T>& st, double full_scale, const ExtractParams& p) {
  if (st.n == 0) return;
  const double scale = full_scale / 255.0;
  st.bg = static_cast<double>(st.scan.sum) / st.n;
  st.mx = st.scan.max;
  st.peak = static_cast<double>(st.mx);
  st.active = !(st.peak - st.bg < p.min_contrast * scale);
}
template <typename T, std::uint32_t Step>
void stage_scan(RowState<T>& st, const T* row, std::uint32_t n, double full_scale, const ExtractParams& p) {
  stage_pass<T, Step>(st, row, n);
  stage_level<T>(st, full_scale, p);
}

template <typename T, std::uint32_t Step>
void support_end(RowState<T>& st, std::int64_t lo, std::int64_t hi, std::int64_t support_sum,
                 double full_scale, const ExtractParams& p);
template <typename T, std::uint32_t Step>
void support_decide(RowState<T>& st, std::int64_t lo, std::int64_t hi, double bg, double full_scale,
                    const ExtractParams& p);

// Stage 2: arg-max, support, background without the support, saturation.
template <typename T, std::uint32_t Step>
void stage_support(RowState<T>& st, double full_scale, const ExtractParams& p) {
  const T* row = st.row;
  const std::uint32_t n = st.n;
  const double peak = st.peak;
  const double bg = st.bg;
  const std::uint32_t imax = first_argmax<T, Step>(row, st.scan, st.mx);
  st.imax = imax;

  // Support of the peak: contiguous samples above bg + 20 % of the contrast, at most max_half_width away.
  // Integer samples: v > low  <=>  v > floor(low).
  const double low = bg + 0.2 * (peak - bg);
  const std::int64_t low_i = static_cast<std::int64_t>(low);  // low >= 0: truncation = floor
  const auto iat = [&](std::int64_t i) {
    return static_cast<std::int64_t>(row[static_cast<std::size_t>(i) * Step]);
  };
  const std::int64_t hw = p.max_half_width;
  std::int64_t lo = imax, hi = imax;
  std::int64_t support_sum = iat(imax);  // summed on the way (no second loop over the support)
  for (std::int64_t v; lo > 0 && imax - lo < hw && (v = iat(lo - 1)) > low_i; --lo) support_sum += v;
  for (std::int64_t v; hi + 1 < n && hi - imax < hw && (v = iat(hi + 1)) > low_i; ++hi) support_sum += v;
  support_end<T, Step>(st, lo, hi, support_sum, full_scale, p);
}

// The rest of stage 2 once the support [lo, hi] and its sum are known (shared with the lane path).
template <typename T, std::uint32_t Step>
void support_end(RowState<T>& st, std::int64_t lo, std::int64_t hi, std::int64_t support_sum,
                 double full_scale, const ExtractParams& p) {
  // Background without the stripe's own energy.
  double bg = st.bg;
  const std::int64_t rest = static_cast<std::int64_t>(st.n) - (hi - lo + 1);
  if (rest > 0)
    bg =
        static_cast<double>(static_cast<std::int64_t>(st.scan.sum) - support_sum) / static_cast<double>(rest);
  support_decide<T, Step>(st, lo, hi, bg, full_scale, p);
}

// Stage 2's decisions once the background without the support is known: contrast, saturation.
template <typename T, std::uint32_t Step>
void support_decide(RowState<T>& st, std::int64_t lo, std::int64_t hi, double bg, double full_scale,
                    const ExtractParams& p) {
  const T* row = st.row;
  const std::uint32_t n = st.n;
  const double scale = full_scale / 255.0;
  const double peak = st.peak;
  const std::uint32_t imax = st.imax;
  st.active = false;
  const double contrast = peak - bg;
  if (contrast < p.min_contrast * scale) return;
  st.r.peak = peak;

  // Saturation plateau.
  if (peak >= full_scale) {
    std::uint32_t run = 0;
    for (std::int64_t i = imax; i < n && at(row, Step, i) >= full_scale; ++i) ++run;
    if (run >= p.saturation_run) {
      st.r.status = RowStatus::Saturated;
      return;
    }
  }
  st.bg = bg;
  st.contrast = contrast;
  st.lo = lo;
  st.hi = hi;
  st.active = true;
}

// GaussMl's half window k: the samples ic +- (3 sigma + 3) with sigma from the FWHM, 4 <= k <= kMaxMlHalf.
constexpr std::int64_t kMaxMlHalf = 64;
inline std::int64_t ml_half_window(double width) {
  const double kw = width * (3.0 / 2.3548);  // >= 0 and small: ceil by truncation
  std::int64_t kc = static_cast<std::int64_t>(std::min(kw, 1e6));
  kc += kw > static_cast<double>(kc) ? 1 : 0;
  return std::clamp<std::int64_t>(kc + 3, 4, kMaxMlHalf);
}

// A GaussMl row's window [first, last] into lane `lane` of the batch (finished by finish_row). src: the row's
// samples at ic - kBatchHalf .. ic + kBatchHalf - 1 when they are all in the row and contiguous, else null;
// fill = false: the lane's samples are in the batch already.
template <typename T, std::uint32_t Step>
void defer_to_batch(RowState<T>& st, detail::GaussMlBatch& batch, int lane, const T* src, std::int64_t ic,
                    std::int64_t first, std::int64_t last, double inv, double clip, bool fill = true) {
  constexpr std::int64_t C = detail::kBatchHalf;
  const double bg = st.bg;
  if (!fill) {
    // filled already (the lane path's lane_fill_batch, the same arithmetic)
  } else if (src) {
    // The whole lane, a fixed trip count in float (vectorized; samples outside [first, last] are masked by
    // the fit).
    const float bgf = static_cast<float>(bg), invf = static_cast<float>(inv);
    for (std::int64_t x = 0; x < 2 * C; ++x) batch.y[x][lane] = (static_cast<float>(src[x]) - bgf) * invf;
  } else {
    for (std::int64_t i = first; i <= last; ++i)
      batch.y[C + (i - ic)][lane] = static_cast<float>((at(st.row, Step, i) - bg) * inv);
  }
  batch.xa[lane] = static_cast<std::int32_t>(first - ic);
  batch.xb[lane] = static_cast<std::int32_t>(last - ic);
  batch.contrast[lane] = st.contrast * inv;
  batch.clip[lane] = clip;
  st.d = Deferred{st.lo, st.hi, ic, bg};
  st.deferred = true;
  st.r.status = RowStatus::Ok;
}

template <typename T, std::uint32_t Step>
bool ambiguous(RowState<T>& st, const ExtractParams& p);
template <typename T, std::uint32_t Step>
void centre_end(RowState<T>& st, double full_scale, const ExtractParams& p, detail::GaussMlBatch& batch,
                int lane, std::int64_t left_end, std::int64_t right_end, std::int64_t top_end);

// Stage 3: the double-peak test, FWHM, and the sub-pixel centre (GaussMl: the row's window into lane `lane`
// of the batch, finished by finish_row once the batch is fitted).
template <typename T, std::uint32_t Step>
void stage_centre(RowState<T>& st, double full_scale, const ExtractParams& p, detail::GaussMlBatch& batch,
                  int lane) {
  const T* row = st.row;
  const double bg = st.bg, contrast = st.contrast;
  const T mx = st.mx;
  const std::uint32_t imax = st.imax;
  const std::int64_t lo = st.lo, hi = st.hi;
  const auto iat = [&](std::int64_t i) {
    return static_cast<std::int64_t>(row[static_cast<std::size_t>(i) * Step]);
  };
  st.active = false;
  if (ambiguous<T, Step>(st, p)) return;

  // Full width at half maximum by linear interpolation on both flanks (integer walks: v > half <=> v >
  // floor).
  const double half = bg + 0.5 * contrast;
  const std::int64_t half_i = static_cast<std::int64_t>(half);  // half >= 0: truncation = floor
  std::int64_t i = imax, j = imax;
  while (i > lo && iat(i - 1) > half_i) --i;
  while (j < hi && iat(j + 1) > half_i) ++j;
  // A flat top of several equal samples: start from its middle.
  std::int64_t top_end = imax;
  while (top_end + 1 <= hi && iat(top_end + 1) >= static_cast<std::int64_t>(mx)) ++top_end;
  centre_end<T, Step>(st, full_scale, p, batch, lane, i, j, top_end);
}

// Stage 3's double-peak test: a second peak outside the support (and the flank sample next to it on each
// side), or a support too wide, makes the row Ambiguous.
template <typename T, std::uint32_t Step>
bool ambiguous(RowState<T>& st, const ExtractParams& p) {
  const std::int64_t lo = st.lo, hi = st.hi;
  const double second_limit = st.bg + p.ambiguous_ratio * st.contrast;
  double second;
  if constexpr (sizeof(T) == 1 && Step == 1)
    second = static_cast<double>(detail::max_outside_u8(st.row, st.scan, lo - 1, hi + 1));
  else
    second = static_cast<double>(detail::max_outside<T, Step>(st.row, st.scan, lo - 1, hi + 1));
  if (second > second_limit || (hi - lo) >= 2 * static_cast<std::int64_t>(p.max_half_width)) {
    st.r.status = RowStatus::Ambiguous;
    return true;
  }
  return false;
}

// The FWHM from the half-maximum walks' ends i (left) and j (right), b and c the samples there, a and d the
// ones past them (has_l / has_r: those exist in the row). Each edge is interpolated where the walk ended on
// the flank (the sample past it at or below half: then b > half >= a and the edge lies in [i - 1, i)); a walk
// stopped by the support's bound (max_half_width) on a stretch still above half keeps the bound
// (interpolating there extrapolated: widths of -4500 px on such rows). The one expression of the per-row,
// lane and mask paths (same bits), written with selects so that their lane loops vectorize.
inline double half_max_width(double a, double b, double c, double d, double half, double i, double j,
                             bool has_l, bool has_r) {
  const bool ul = has_l && a <= half, ur = has_r && d <= half;
  const double ql = (b - half) / (ul ? b - a : 1.0), qr = (c - half) / (ur ? c - d : 1.0);
  return (ur ? j + qr : j) - (ul ? i - ql : i);
}

// The rest of stage 3 once the half-maximum walks ended at i (left) and j (right) and the flat top at top_end
// (shared with the lane path).
template <typename T, std::uint32_t Step>
void centre_end(RowState<T>& st, double full_scale, const ExtractParams& p, detail::GaussMlBatch& batch,
                int lane, std::int64_t left_end, std::int64_t right_end, std::int64_t top_end) {
  const T* row = st.row;
  const std::uint32_t n = st.n;
  const double scale = full_scale / 255.0;
  const double bg = st.bg, contrast = st.contrast;
  const std::uint32_t imax = st.imax;
  const std::int64_t lo = st.lo, hi = st.hi;
  RowPeak& r = st.r;
  {
    const std::int64_t i = left_end, j = right_end;
    const bool has_l = i > 0, has_r = j + 1 < n;
    r.width = half_max_width(at(row, Step, i - (has_l ? 1 : 0)), at(row, Step, i), at(row, Step, j),
                             at(row, Step, j + (has_r ? 1 : 0)), bg + 0.5 * contrast, static_cast<double>(i),
                             static_cast<double>(j), has_l, has_r);
  }

  const auto v = [&](std::int64_t i) {
    if (i < 0 || i >= static_cast<std::int64_t>(n)) return 0.0;
    return std::max(0.0, at(row, Step, i) - bg);
  };
  double col = static_cast<double>(imax);
  const std::int64_t ic = (imax + top_end) / 2;
  switch (p.method) {
    case SubpixelMethod::CentreOfGravity: {
      const std::int64_t w = p.cog_half_window;
      double s = 0.0, sw = 0.0;
      for (std::int64_t i = ic - w; i <= ic + w; ++i) {
        const double x = v(i);
        s += x;
        sw += x * static_cast<double>(i);
      }
      col = s > 0.0 ? sw / s : static_cast<double>(ic);
      break;
    }
    case SubpixelMethod::Gaussian3: {
      const double a = std::log(std::max(v(ic - 1), 0.5)), b = std::log(std::max(v(ic), 0.5)),
                   c = std::log(std::max(v(ic + 1), 0.5));
      const double den = a - 2.0 * b + c;
      double d = den < 0.0 ? 0.5 * (a - c) / den : 0.0;
      col = static_cast<double>(ic) + std::clamp(d, -0.5, 0.5);
      break;
    }
    case SubpixelMethod::GaussFit: {
      // Weighted LS fit of ln v = a + b x + c x^2 (x = i - ic), weights v^2; centre = ic - b / (2c).
      double s0 = 0, s1 = 0, s2 = 0, s3 = 0, s4 = 0, t0 = 0, t1 = 0, t2 = 0;
      const double floor_v = 0.2 * contrast;
      for (std::int64_t i = lo; i <= hi; ++i) {
        const double y = v(i);
        if (y <= floor_v) continue;
        const double w = y * y, x = static_cast<double>(i - ic), ly = std::log(y);
        const double x2 = x * x;
        s0 += w;
        s1 += w * x;
        s2 += w * x2;
        s3 += w * x2 * x;
        s4 += w * x2 * x2;
        t0 += w * ly;
        t1 += w * x * ly;
        t2 += w * x2 * ly;
      }
      // Solve the 3x3 normal equations [s0 s1 s2; s1 s2 s3; s2 s3 s4] [a b c] = [t0 t1 t2] (Cramer).
      const double det = s0 * (s2 * s4 - s3 * s3) - s1 * (s1 * s4 - s3 * s2) + s2 * (s1 * s3 - s2 * s2);
      col = static_cast<double>(ic);
      if (std::abs(det) > 1e-12) {
        const double db = s0 * (t1 * s4 - s3 * t2) - t0 * (s1 * s4 - s3 * s2) + s2 * (s1 * t2 - t1 * s2);
        const double dc = s0 * (s2 * t2 - t1 * s3) - s1 * (s1 * t2 - t1 * s2) + t0 * (s1 * s3 - s2 * s2);
        const double b = db / det, c = dc / det;
        if (c < 0.0) col = static_cast<double>(ic) + std::clamp(-b / (2.0 * c), -2.0, 2.0);
      }
      break;
    }
    case SubpixelMethod::GaussMl:
    case SubpixelMethod::GaussLog: {
      // Samples minus background in 8-bit DN over ic +- (3 sigma + 3), sigma from the FWHM.
      const std::int64_t k = ml_half_window(r.width);
      const std::int64_t first = std::max<std::int64_t>(0, ic - k);
      const std::int64_t last = std::min<std::int64_t>(static_cast<std::int64_t>(n) - 1, ic + k);
      const double inv = 1.0 / scale;
      const double clip = (full_scale - bg) * inv;
      if (k < detail::kBatchHalf) {  // the batched fit (every stripe narrower than ~9 px FWHM)
        const T* src = Step == 1 && ic - detail::kBatchHalf >= 0 &&
                               ic + detail::kBatchHalf <= static_cast<std::int64_t>(n)
                           ? row + (ic - detail::kBatchHalf)
                           : nullptr;
        defer_to_batch<T, Step>(st, batch, lane, src, ic, first, last, inv, clip);
        return;
      }
      std::array<float, 2 * kMaxMlHalf + 1 + detail::kChunk> y;
      const std::int64_t count = last - first + 1;
      for (std::int64_t i = 0; i < count; ++i)
        y[static_cast<std::size_t>(i)] = static_cast<float>((at(row, Step, first + i) - bg) * inv);
      std::fill_n(y.begin() + count, detail::kChunk,
                  0.0f);  // the fit reads (and masks out) up to kChunk more
      const detail::SensorNoise noise{p.read_noise, p.shot_noise, p.speckle};
      double c = 0.0;
      if (detail::gauss_ml_centre(y.data(), static_cast<int>(last - first + 1), static_cast<int>(ic - first),
                                  contrast * inv, clip, noise, c, p.method == SubpixelMethod::GaussMl)) {
        col = static_cast<double>(first) + c;
      } else {
        col = support_cog<T, Step>(row, lo, hi, ic, bg);
      }
      break;
    }
    case SubpixelMethod::BlaisRioux: {
      // 4th-order derivative filter g(j) = f(j-2) + f(j-1) - f(j+1) - f(j+2); the centre is its zero
      // crossing.
      const auto g = [&](std::int64_t j) { return v(j - 2) + v(j - 1) - v(j + 1) - v(j + 2); };
      const double g0 = g(ic);
      std::int64_t j = g0 > 0.0 ? ic - 1 : ic;
      const double gj = g(j), gj1 = g(j + 1);
      col = (gj <= 0.0 && gj1 > 0.0 && gj1 != gj) ? static_cast<double>(j) + gj / (gj - gj1)
                                                  : static_cast<double>(ic);
      break;
    }
  }
  // A stripe's centre lies within its support (guards every method against edge extrapolation).
  r.col = std::clamp(col, static_cast<double>(lo) - 0.5, static_cast<double>(hi) + 0.5);
  r.status = RowStatus::Ok;
}

// Stages 2 and 3 for a block of 8-bit rows with the walks in SIMD lanes (row_lanes.hpp), one row per lane:
// the same decisions and results as stage_support + stage_centre row by row (the walks give the same counts,
// the rest is the same code). Needs max_half_width <= kMaxLaneWalk; extract_rows and extract_row take it for
// GaussMl rows only (lane_path), but it gives every method's results (the others through centre_end).
template <std::uint32_t Step>
void stage_lanes(RowState<std::uint8_t>* st, int rows, double full_scale, const ExtractParams& p,
                 detail::GaussMlBatch& batch, detail::LaneWindow& win) {
  using detail::kWinHalf;
  using detail::LaneI16;
  static_assert(detail::kLaneRows == detail::kBatch);
  constexpr std::int16_t kNever = 32767;  // a threshold no 8-bit sample exceeds: the lane walks nowhere
  alignas(16) std::int16_t low[detail::kLaneRows], top[detail::kLaneRows];
  for (int l = 0; l < detail::kLaneRows; ++l) {
    low[l] = top[l] = kNever;
    if (l >= rows || !st[l].active) continue;
    RowState<std::uint8_t>& s = st[l];
    s.imax = first_argmax<std::uint8_t, Step>(s.row, s.scan, s.mx);
    detail::lane_window_fill<Step>(win, l, s.row, s.n, s.imax);
    low[l] = static_cast<std::int16_t>(s.bg + 0.2 * (s.peak - s.bg));  // >= 0: truncation = floor
    top[l] = s.mx;
  }
  detail::lane_window_transpose(win);
  LaneI16 lowv, topv;
  std::memcpy(&lowv, low, sizeof lowv);
  std::memcpy(&topv, top, sizeof topv);
  const int hw = static_cast<int>(p.max_half_width);
  const detail::LaneSupport sup = detail::lane_support_walks(win, lowv, topv, hw);

  // Background without the support, contrast, in double lanes (every lane: the idle ones on harmless values).
  constexpr int L = detail::kLaneRows;
  alignas(64) double total[L], rest[L], bg0[L], peak[L], bg[L], contrast[L];
  for (int l = 0; l < L; ++l) {
    const bool act = l < rows && st[l].active;
    const std::int64_t width = sup.left[l] + sup.right[l] + 1;
    total[l] = act ? static_cast<double>(static_cast<std::int64_t>(st[l].scan.sum) - win.raw[l][kWinHalf] -
                                         sup.sum[l])
                   : 0.0;
    rest[l] = act ? static_cast<double>(static_cast<std::int64_t>(st[l].n) - width) : 1.0;
    bg0[l] = act ? st[l].bg : 0.0;
    peak[l] = act ? st[l].peak : 0.0;
  }
  for (int l = 0; l < L; ++l) {
    const double b = total[l] / (rest[l] > 0.0 ? rest[l] : 1.0);
    bg[l] = rest[l] > 0.0 ? b : bg0[l];
    contrast[l] = peak[l] - bg[l];
  }
  const double min_contrast = p.min_contrast * (full_scale / 255.0);
  alignas(16) std::int16_t half[L], lmax[L], rmax[L];
  int walk = 0;
  bool any = false;
  for (int l = 0; l < L; ++l) {
    half[l] = kNever;
    lmax[l] = rmax[l] = 0;
    if (l >= rows || !st[l].active) continue;
    RowState<std::uint8_t>& s = st[l];
    s.active = false;
    if (contrast[l] < min_contrast) continue;  // the common exit before support_decide, without the call
    const std::int64_t im = s.imax;
    support_decide<std::uint8_t, Step>(s, im - sup.left[l], im + sup.right[l], bg[l], full_scale, p);
    if (!s.active) continue;
    any = true;  // the double-peak test after the walks (below): the lane walks either way
    half[l] = static_cast<std::int16_t>(s.bg + 0.5 * s.contrast);  // >= 0: truncation = floor
    lmax[l] = sup.left[l];
    rmax[l] = sup.right[l];
    walk = std::max<int>(walk, std::max(lmax[l], rmax[l]));
  }
  if (!any) return;
  LaneI16 halfv, lmaxv, rmaxv, left, right;
  std::memcpy(&halfv, half, sizeof halfv);
  std::memcpy(&lmaxv, lmax, sizeof lmaxv);
  std::memcpy(&rmaxv, rmax, sizeof rmaxv);
  detail::lane_half_walks(win, halfv, lmaxv, rmaxv, walk, left, right);

  // The FWHM by interpolation on both flanks, in double lanes: centre_end's formulas, the samples at the
  // walks' ends from the windows (0 outside the row, where the conditions i > 0, j + 1 < n exclude them
  // anyway).
  alignas(64) double a[L], b[L], c[L], d[L], hv[L], iv[L], jv[L], width[L];
  alignas(64) std::int32_t ok_l[L], ok_r[L];
  for (int l = 0; l < L; ++l) {
    const bool act = l < rows && st[l].active;
    const int li = kWinHalf - left[l], rj = kWinHalf + right[l];
    const std::int64_t im = act ? st[l].imax : 0, n = act ? st[l].n : 0;
    const std::int64_t i = im - left[l], j = im + right[l];
    a[l] = win.raw[l][li - 1];
    b[l] = win.raw[l][li];
    c[l] = win.raw[l][rj];
    d[l] = win.raw[l][rj + 1];
    hv[l] = act ? st[l].bg + 0.5 * st[l].contrast : 0.0;
    iv[l] = static_cast<double>(i);
    jv[l] = static_cast<double>(j);
    ok_l[l] = i > 0;
    ok_r[l] = j + 1 < n;
  }
  for (int l = 0; l < L; ++l)
    width[l] = half_max_width(a[l], b[l], c[l], d[l], hv[l], iv[l], jv[l], ok_l[l] != 0, ok_r[l] != 0);
  const double inv = 1.0 / (full_scale / 255.0);  // centre_end's 1 / scale
  alignas(64) std::int64_t ic_l[L], first_l[L], last_l[L];
  alignas(64) float bgf[L];
  bool batched[L] = {}, from_window[L] = {}, any_window = false;
  for (int l = 0; l < L; ++l) bgf[l] = 0.0f;
  for (int l = 0; l < rows; ++l) {
    RowState<std::uint8_t>& s = st[l];
    if (!s.active) continue;
    s.active = false;
    if (ambiguous<std::uint8_t, Step>(s, p)) continue;
    const std::int64_t im = s.imax;
    const std::int64_t ic = (im + im + sup.top[l]) / 2;
    const std::int64_t k = ml_half_window(width[l]);
    if (!fits_in_batch(p.method) || k >= detail::kBatchHalf) {  // the per-row code
      centre_end<std::uint8_t, Step>(s, full_scale, p, batch, l, im - left[l], im + right[l],
                                     im + sup.top[l]);
      continue;
    }
    s.r.width = width[l];
    const std::int64_t n = s.n;
    ic_l[l] = ic;
    first_l[l] = std::max<std::int64_t>(0, ic - k);
    last_l[l] = std::min<std::int64_t>(n - 1, ic + k);
    batched[l] = true;
    // The whole lane from the window when its samples all lie in the row: across the lanes at once (below)
    // where the lane starts at imax - kBatchHalf (no flat top to the right: the common case).
    from_window[l] = Step == 1 && ic - detail::kBatchHalf >= 0 && ic + detail::kBatchHalf <= n && ic == im;
    bgf[l] = from_window[l] ? static_cast<float>(s.bg) : 0.0f;
    any_window |= from_window[l];
  }
  if (any_window) detail::lane_fill_batch<detail::kBatchHalf>(win, bgf, static_cast<float>(inv), batch.y);
  for (int l = 0; l < rows; ++l) {
    if (!batched[l]) continue;
    RowState<std::uint8_t>& s = st[l];
    const std::int64_t ic = ic_l[l], im = s.imax, n = s.n;
    const bool whole = Step == 1 && ic - detail::kBatchHalf >= 0 && ic + detail::kBatchHalf <= n;
    const std::uint8_t* src = whole ? win.raw[l] + (kWinHalf + (ic - im) - detail::kBatchHalf) : nullptr;
    defer_to_batch<std::uint8_t, Step>(s, batch, l, src, ic, first_l[l], last_l[l], inv,
                                       (full_scale - s.bg) * inv, !from_window[l]);
  }
}

#if defined(__x86_64__)
// stage_lanes for contiguous 8-bit rows on x86-64 CPUs with AVX2 (masks_supported()): each row's walks as bit
// masks of its 64-sample window (row_masks.hpp) instead of lane walks over transposed windows, and the
// batch's input converted per row and transposed once per block. Three passes over the block's rows (support
// and background; contrast, saturation and FWHM; double-peak test and the centre's window), so that the rows'
// dependency chains (arg-max, masks, divisions) overlap as in stage_lanes. The same arithmetic in the same
// order as stage_lanes and the per-row code (same bits, tests/firmware/extract_lanes_test.cpp); compiled for
// AVX2 without FMA (no contraction: the double expressions round as in the portable build).
FS_ROW_MASKS_TARGET void stage_masks(RowState<std::uint8_t>* st, int rows, double full_scale,
                                     const ExtractParams& p, detail::GaussMlBatch& batch,
                                     detail::LaneWindow& win) {
  using detail::kWinHalf;
  constexpr int C = detail::kBatchHalf, L = detail::kBatch;
  const int hw = static_cast<int>(p.max_half_width);
  const double min_contrast = p.min_contrast * (full_scale / 255.0);
  const double inv = 1.0 / (full_scale / 255.0);  // centre_end's 1 / scale
  int left[L], right[L], top[L], left2[L], right2[L];
  // the rows' divisions in loops of their own after the loops that feed them (independent of each other, so
  // they overlap in the core; GCC keeps them scalar: vdivsd)
  alignas(64) double total[L] = {}, rest[L], bg0[L] = {}, bg[L];
  alignas(64) double fa[L] = {}, fb[L] = {}, fc[L] = {}, fd[L] = {}, hv[L] = {}, fi[L] = {}, fj[L] = {},
                     width[L];
  alignas(64) std::int64_t ok_l[L] = {}, ok_r[L] = {};
  bool live[L];
  for (int l = 0; l < L; ++l) rest[l] = 1.0;
  // 1. Arg-max, window, support walks and sum, background without the support.
  for (int l = 0; l < rows; ++l) {
    RowState<std::uint8_t>& s = st[l];
    live[l] = s.active;
    if (!live[l]) continue;
    s.active = false;
    const std::uint8_t* row = s.row;
    const std::uint32_t imax = detail::masks::first_argmax(row, s.scan, s.mx);
    s.imax = imax;
    std::uint8_t* raw = win.raw[l];
    // Straight from the row (a load right after the copy's stores would wait for them), kept for passes 2
    // and 3.
    detail::masks::Window w;
    if (static_cast<std::int64_t>(imax) < kWinHalf || imax + kWinHalf > s.n) {
      detail::window_fill<1>(raw, row, s.n, imax);
      w = detail::masks::load(raw);
    } else {
      w = detail::masks::load(row + (imax - kWinHalf));
      detail::masks::store(raw, w);
    }
    const int low = static_cast<std::int16_t>(s.bg + 0.2 * (s.peak - s.bg));  // >= 0: truncation = floor
    const std::uint64_t above_low = detail::masks::above(w, low);
    left[l] = detail::masks::run_left(above_low, hw);
    right[l] = detail::masks::run_right(above_low, hw);
    top[l] = detail::masks::run_right(detail::masks::equal(w, s.mx), right[l]);
    const std::int64_t supsum = detail::masks::support_sum(w, left[l], right[l]);
    // stage_lanes' expressions
    total[l] = static_cast<double>(static_cast<std::int64_t>(s.scan.sum) - raw[kWinHalf] - supsum);
    rest[l] = static_cast<double>(static_cast<std::int64_t>(s.n) - (left[l] + right[l] + 1));
    bg0[l] = s.bg;
  }
  for (int l = 0; l < L; ++l) {  // the background without the support
    const double b = total[l] / (rest[l] > 0.0 ? rest[l] : 1.0);
    bg[l] = rest[l] > 0.0 ? b : bg0[l];
  }
  // 2. Contrast and saturation (support_decide), half-maximum walks inside the support, FWHM.
  for (int l = 0; l < rows; ++l) {
    if (!live[l]) continue;
    RowState<std::uint8_t>& s = st[l];
    live[l] = false;
    if (s.peak - bg[l] < min_contrast) continue;
    const std::int64_t im = s.imax, n = s.n;
    support_decide<std::uint8_t, 1>(s, im - left[l], im + right[l], bg[l], full_scale, p);
    if (!s.active) continue;
    s.active = false;
    live[l] = true;
    const std::uint8_t* raw = win.raw[l];
    hv[l] = s.bg + 0.5 * s.contrast;
    const std::uint64_t above_half =
        detail::masks::above(detail::masks::load(raw), static_cast<std::int16_t>(hv[l]));
    left2[l] = detail::masks::run_left(above_half, left[l]);
    right2[l] = detail::masks::run_right(above_half, right[l]);
    const int li = kWinHalf - left2[l], rj = kWinHalf + right2[l];
    fa[l] = raw[li - 1];
    fb[l] = raw[li];
    fc[l] = raw[rj];
    fd[l] = raw[rj + 1];
    const std::int64_t i = im - left2[l], j = im + right2[l];
    fi[l] = static_cast<double>(i);
    fj[l] = static_cast<double>(j);
    ok_l[l] = i > 0;
    ok_r[l] = j + 1 < n;
  }
  for (int l = 0; l < L; ++l)  // the FWHM, the rows side by side
    width[l] = half_max_width(fa[l], fb[l], fc[l], fd[l], hv[l], fi[l], fj[l], ok_l[l] != 0, ok_r[l] != 0);
  // 3. Double-peak test, then the centre: the batch's lane (or the per-row code).
  alignas(32) float lane_y[L][2 * C];  // the whole lanes' fit inputs, row-major (transposed below)
  bool any_whole = false, edge[L] = {};
  std::int64_t edge_ic[L], edge_first[L],
      edge_last[L];  // the edge lanes' windows, filled after the transpose
  for (int l = 0; l < rows; ++l) {
    if (!live[l]) continue;
    RowState<std::uint8_t>& s = st[l];
    if (ambiguous<std::uint8_t, 1>(s, p)) continue;
    const std::int64_t im = s.imax, n = s.n;
    const std::int64_t ic = (im + im + top[l]) / 2;
    const std::int64_t k = ml_half_window(width[l]);
    if (!fits_in_batch(p.method) || k >= C) {  // the per-row code
      centre_end<std::uint8_t, 1>(s, full_scale, p, batch, l, im - left2[l], im + right2[l], im + top[l]);
      continue;
    }
    s.r.width = width[l];
    const std::int64_t first = std::max<std::int64_t>(0, ic - k),
                       last = std::min<std::int64_t>(n - 1, ic + k);
    const bool whole = ic - C >= 0 && ic + C <= n;
    edge[l] = !whole;
    if (!whole) {  // after the transpose, which writes every lane: defer_to_batch's per-sample fill
      edge_ic[l] = ic;
      edge_first[l] = first;
      edge_last[l] = last;
      continue;
    }
    // the lane's 32 samples from the window (ic - imax = top / 2 <= 15); then lanes without a row hold finite
    // values too
    detail::masks::fill_lane(win.raw[l] + (kWinHalf + (ic - im) - C), static_cast<float>(s.bg),
                             static_cast<float>(inv), lane_y[l]);
    any_whole = true;
    defer_to_batch<std::uint8_t, 1>(s, batch, l, nullptr, ic, first, last, inv, (full_scale - s.bg) * inv,
                                    false);
  }
  if (any_whole) {
    for (int l = 0; l < L; ++l)  // lanes without a whole window: finite placeholders
      if (l >= rows || !st[l].deferred) std::memset(lane_y[l], 0, sizeof lane_y[l]);
    detail::masks::transpose_lanes(lane_y, batch.y);
  }
  for (int l = 0; l < rows; ++l)
    if (edge[l])
      defer_to_batch<std::uint8_t, 1>(st[l], batch, l, nullptr, edge_ic[l], edge_first[l], edge_last[l], inv,
                                      (full_scale - st[l].bg) * inv);
}
#endif

// Completes a row analyse_row deferred, once its batch has been fitted.
template <typename T, std::uint32_t Step>
void finish_row(const T* row, const Deferred& d, const detail::GaussMlBatch& batch, int lane, RowPeak& r) {
  const double col = batch.ok[lane] ? static_cast<double>(d.ic) + batch.centre[lane]
                                    : support_cog<T, Step>(row, d.lo, d.hi, d.ic, d.bg);
  // A stripe's centre lies within its support (guards every method against edge extrapolation).
  r.col = std::clamp(col, static_cast<double>(d.lo) - 0.5, static_cast<double>(d.hi) + 0.5);
}

// 8-bit GaussMl rows take the lane path (stage_lanes) unless the walks could leave its window. The other
// methods keep the per-row walks: measured 2-12 % faster for them (the lane path pays off through the batch's
// lane fill).
inline bool lane_path(const ExtractParams& p) {
  return fits_in_batch(p.method) && p.max_half_width <= static_cast<std::uint32_t>(detail::kMaxLaneWalk);
}

// Which code a lane-path block of 8-bit rows takes: the bit-mask walks (stage_masks: contiguous rows on
// x86-64 CPUs with AVX2, BMI1 and LZCNT; detected once) or the lane walks (stage_lanes: YUYV, other CPUs and
// targets). Walks::Rows: the per-row walks (detail::extract_row_per_row_walks, the reference).
using Walks = detail::Walks;
inline bool masks_supported() {
#if defined(__x86_64__)
  static const bool ok = [] {
    __builtin_cpu_init();
    // LZCNT (ABM): CPUID 0x80000001 ECX bit 5 (clang's __builtin_cpu_supports has no "lzcnt")
    unsigned a = 0, b = 0, c = 0, d = 0;
    const bool lzcnt = __get_cpuid(0x80000001u, &a, &b, &c, &d) && (c & (1u << 5));
    return detail::cpu_has_avx2() && __builtin_cpu_supports("bmi") && lzcnt;
  }();
  return ok;
#else
  return false;
#endif
}
template <std::uint32_t Step>
void stage_walks(RowState<std::uint8_t>* st, int rows, double full_scale, const ExtractParams& p,
                 detail::GaussMlBatch& batch, detail::LaneWindow& win, [[maybe_unused]] Walks walks) {
#if defined(__x86_64__)
  if constexpr (Step == 1) {
    if (walks == Walks::Best && masks_supported()) {
      stage_masks(st, rows, full_scale, p, batch, win);
      return;
    }
  }
#endif
  stage_lanes<Step>(st, rows, full_scale, p, batch, win);
}

// One row alone (extract_row): the stages back to back, a batch of one.
template <typename T, std::uint32_t Step>
RowPeak extract_row_impl(const T* row, std::uint32_t n, double full_scale, const ExtractParams& p,
                         Walks walks = Walks::Best) {
  RowState<T> st;
  detail::GaussMlBatch batch;
  batch.intensity_step = p.method == SubpixelMethod::GaussMl;
  stage_scan<T, Step>(st, row, n, full_scale, p);
  if constexpr (sizeof(T) == 1) {
    if (walks != Walks::Rows && lane_path(p)) {
      detail::LaneWindow win{};
      if (st.active) stage_walks<Step>(&st, 1, full_scale, p, batch, win, walks);
    }
  }
  if (st.active) stage_support<T, Step>(st, full_scale, p);
  if (st.active) stage_centre<T, Step>(st, full_scale, p, batch, 0);
  if (st.deferred) {
    detail::gauss_ml_centre_batch(batch, detail::SensorNoise{p.read_noise, p.shot_noise, p.speckle});
    finish_row<T, Step>(row, st.d, batch, 0, st.r);
  }
  return st.r;
}

}  // namespace

template <>
RowPeak extract_row<std::uint8_t>(const std::uint8_t* row, std::uint32_t n, std::uint32_t step,
                                  double full_scale, const ExtractParams& p) {
  return step == 2 ? extract_row_impl<std::uint8_t, 2>(row, n, full_scale, p)
                   : extract_row_impl<std::uint8_t, 1>(row, n, full_scale, p);
}

RowPeak detail::extract_row_per_row_walks(const std::uint8_t* row, std::uint32_t n, std::uint32_t step,
                                          double full_scale, const ExtractParams& p) {
  return step == 2 ? extract_row_impl<std::uint8_t, 2>(row, n, full_scale, p, Walks::Rows)
                   : extract_row_impl<std::uint8_t, 1>(row, n, full_scale, p, Walks::Rows);
}

RowPeak detail::extract_row_lane_walks(const std::uint8_t* row, std::uint32_t n, std::uint32_t step,
                                       double full_scale, const ExtractParams& p) {
  return step == 2 ? extract_row_impl<std::uint8_t, 2>(row, n, full_scale, p, Walks::Lanes)
                   : extract_row_impl<std::uint8_t, 1>(row, n, full_scale, p, Walks::Lanes);
}

const char* detail::extract_walks_isa() { return masks_supported() ? "bit masks (avx2)" : "lanes"; }

template <>
RowPeak extract_row<std::uint16_t>(const std::uint16_t* row, std::uint32_t n, std::uint32_t /*step*/,
                                   double full_scale, const ExtractParams& p) {
  return extract_row_impl<std::uint16_t, 1>(row, n, full_scale, p);
}

namespace {

// Requests the `bytes` bytes at p into the caches: every 64-byte cache line they touch, the first and last of
// a row that does not start on a line included (ExtractParams::prefetch_rows; a prefetch never faults).
inline void prefetch_row(const std::uint8_t* p, std::size_t bytes) {
  const std::uintptr_t first = reinterpret_cast<std::uintptr_t>(p) & ~std::uintptr_t{63};
  const std::uintptr_t end = reinterpret_cast<std::uintptr_t>(p) + bytes;
  // 4 lines an iteration: one loop test per 4 prefetches (a 1280-byte row: 21 lines, ~45 instructions fewer)
#pragma GCC unroll 4
  for (std::uintptr_t a = first; a < end; a += 64) __builtin_prefetch(reinterpret_cast<const void*>(a), 0, 3);
}

// Rows in blocks of kBatch: each stage over the block's rows (row pass; support and background; shape and
// centre, GaussMl rows into the lanes of the batch), then one batched GaussMl fit for the block, then the
// block's points in row order.
template <typename T, std::uint32_t Step>
void extract_rows(const FrameView& f, double full_scale, const ExtractParams& params,
                  std::span<msg::StripePoint> out, ExtractCounts& c, Walks walks) {
  constexpr int L = detail::kBatch;
  RowState<T> st[L];
  detail::GaussMlBatch batch;
  batch.intensity_step = params.method == SubpixelMethod::GaussMl;
  const detail::SensorNoise noise{params.read_noise, params.shot_noise, params.speckle};
  detail::LaneWindow win{};
  const bool lanes = walks != Walks::Rows && lane_path(params);
  for (std::uint32_t y0 = 0; y0 < f.height; y0 += L) {
    const int rows = static_cast<int>(std::min<std::uint32_t>(L, f.height - y0));
    for (int i = 0; i < rows; ++i) {
      const auto* row = reinterpret_cast<const T*>(
          f.data + static_cast<std::size_t>(y0 + static_cast<std::uint32_t>(i)) * f.stride);
      stage_pass<T, Step>(st[i], row, f.width);
      if (const std::uint8_t* ahead =
              detail::prefetch_target(f, y0 + static_cast<std::uint32_t>(i), params.prefetch_rows))
        prefetch_row(ahead, static_cast<std::size_t>(f.width) * sizeof(T) * Step);
    }
    for (int i = 0; i < rows; ++i) stage_level<T>(st[i], full_scale, params);
    if constexpr (sizeof(T) == 1) {
      if (lanes) stage_walks<Step>(st, rows, full_scale, params, batch, win, walks);
    }
    for (int i = 0; i < rows; ++i)
      if (st[i].active) stage_support<T, Step>(st[i], full_scale, params);
    bool any = false;
    for (int i = 0; i < rows; ++i) {
      if (st[i].active) stage_centre<T, Step>(st[i], full_scale, params, batch, i);
      if (!st[i].deferred) batch.xa[i] = batch.xb[i] = 0;  // an unused lane
      any |= st[i].deferred;
    }
    if (any) {
      for (int i = rows; i < L; ++i) batch.xa[i] = batch.xb[i] = 0;
      detail::gauss_ml_centre_batch(batch, noise);
      for (int i = 0; i < rows; ++i)
        if (st[i].deferred) finish_row<T, Step>(st[i].row, st[i].d, batch, i, st[i].r);
    }
    for (int i = 0; i < rows; ++i) {
      const RowPeak& r = st[i].r;
      ++c.rows;
      switch (r.status) {
        case RowStatus::NoStripe:
          ++c.no_stripe;
          continue;
        case RowStatus::Ambiguous:
          ++c.ambiguous;
          continue;
        case RowStatus::Saturated:
          ++c.saturated;
          continue;
        case RowStatus::Ok:
          break;
      }
      if (c.points >= out.size()) continue;
      msg::StripePoint& pt = out[c.points++];
      pt.row = static_cast<std::uint16_t>(y0 + static_cast<std::uint32_t>(i));
      pt.col = static_cast<float>(r.col);
      pt.peak = static_cast<std::uint16_t>(std::min(r.peak, 65535.0));
      pt.width = static_cast<float>(r.width);
    }
  }
}

}  // namespace

const std::uint8_t* detail::prefetch_target(const FrameView& f, std::uint32_t y, std::uint32_t rows) {
  // y < f.height: the subtraction does not wrap, nor does y + rows get formed
  if (rows == 0 || y >= f.height || rows >= f.height - y) return nullptr;
  return f.data + (static_cast<std::size_t>(y) + rows) * f.stride;
}

ExtractCounts extract_frame(const FrameView& f, const ExtractParams& params,
                            std::span<msg::StripePoint> out) {
  return detail::extract_frame_walks(f, params, out, Walks::Best);
}

ExtractCounts detail::extract_frame_walks(const FrameView& f, const ExtractParams& params,
                                          std::span<msg::StripePoint> out, Walks walks) {
  ExtractCounts c;
  if (!f.data || f.width == 0 || f.height == 0) return c;
  switch (f.format) {
    case PixelFormat::Mono8:
      extract_rows<std::uint8_t, 1>(f, 255.0, params, out, c, walks);
      break;
    case PixelFormat::Yuyv:
      extract_rows<std::uint8_t, 2>(f, 255.0, params, out, c, walks);
      break;
    case PixelFormat::Mono16:
      extract_rows<std::uint16_t, 1>(f, 65535.0, params, out, c, walks);
      break;
  }
  if (params.along_stripe >= 3) {
    const std::span<msg::StripePoint> pts = out.first(std::min<std::size_t>(c.points, out.size()));
    refine_along_stripe(pts, params.along_stripe, along_stripe_scale(pts, params.along_stripe));
    // A line through the neighbours can end a little past the row's first or last pixel (a stripe along the
    // frame's edge): the centre stays inside the row, as the per-row centres do (found by the fuzz target).
    const float last = static_cast<float>(f.width) - 0.5f;
    for (msg::StripePoint& pt : pts) pt.col = std::clamp(pt.col, -0.5f, last);
  }
  return c;
}

}  // namespace fs::fw
