// Stages 2 and 3 of a block of contiguous 8-bit rows with the walks as AVX2 bit masks (row_masks.hpp), on
// x86-64 CPUs that have AVX2, BMI1 and LZCNT (masks_supported(), detected once at run time).
#include <algorithm>
#include <cstring>

#include "firmware/extract/stripe_stages.hpp"

#if defined(__x86_64__)
#include <cpuid.h>
#endif

namespace fs::fw::detail::stripe {

bool masks_supported() {
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

}  // namespace fs::fw::detail::stripe
