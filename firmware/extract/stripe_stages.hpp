#pragma once
// The stages of one row's analysis (stripe_extractor.cpp): state, row pass and levels (stage 1), support and
// background (stage 2), double-peak test and half-maximum walks (stage 3), the batched fit's lanes, and the
// entry points of the stages in other files: the sub-pixel centre (stripe_centre.cpp), the walks of a block
// of 8-bit rows in SIMD lanes (stripe_lane_walks.cpp) and as AVX2 bit masks (stripe_mask_walks.cpp). Internal
// to firmware/extract; every file that includes it is built with -ffp-contract=off (firmware/CMakeLists.txt).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include "firmware/extract/gauss_ml.hpp"
#include "firmware/extract/row_lanes.hpp"
#include "firmware/extract/row_masks.hpp"
#include "firmware/extract/row_scan.hpp"
#include "firmware/extract/stripe_extractor.hpp"

namespace fs::fw::detail::stripe {

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
// (interpolating there would extrapolate, to widths far outside the row). The one expression of the per-row,
// lane and mask paths (same bits), written with selects so that their lane loops vectorize.
inline double half_max_width(double a, double b, double c, double d, double half, double i, double j,
                             bool has_l, bool has_r) {
  const bool ul = has_l && a <= half, ur = has_r && d <= half;
  const double ql = (b - half) / (ul ? b - a : 1.0), qr = (c - half) / (ur ? c - d : 1.0);
  return (ur ? j + qr : j) - (ul ? i - ql : i);
}

// Completes a row analyse_row deferred, once its batch has been fitted.
template <typename T, std::uint32_t Step>
void finish_row(const T* row, const Deferred& d, const detail::GaussMlBatch& batch, int lane, RowPeak& r) {
  const double col = batch.ok[lane] ? static_cast<double>(d.ic) + batch.centre[lane]
                                    : support_cog<T, Step>(row, d.lo, d.hi, d.ic, d.bg);
  // A stripe's centre lies within its support (guards every method against edge extrapolation).
  r.col = std::clamp(col, static_cast<double>(d.lo) - 0.5, static_cast<double>(d.hi) + 0.5);
}

// 8-bit GaussMl rows take the lane path (stage_lanes) unless the walks could leave its window. The other
// methods keep the per-row walks, faster for them (the lane path pays off through the batch's lane fill;
// bench_extract --benchmark_filter=Extract runs each method).
inline bool lane_path(const ExtractParams& p) {
  return fits_in_batch(p.method) && p.max_half_width <= static_cast<std::uint32_t>(detail::kMaxLaneWalk);
}

// The walks of a block of 8-bit rows, one row per SIMD lane (stripe_lane_walks.cpp; Step 1 and 2).
template <std::uint32_t Step>
void stage_lanes(RowState<std::uint8_t>* st, int rows, double full_scale, const ExtractParams& p,
                 detail::GaussMlBatch& batch, detail::LaneWindow& win);

// Whether this CPU takes the bit-mask walks (stripe_mask_walks.cpp): x86-64 with AVX2, BMI1 and LZCNT.
bool masks_supported();
#if defined(__x86_64__)
FS_ROW_MASKS_TARGET void stage_masks(RowState<std::uint8_t>* st, int rows, double full_scale,
                                     const ExtractParams& p, detail::GaussMlBatch& batch,
                                     detail::LaneWindow& win);
#endif

}  // namespace fs::fw::detail::stripe
