// Stages 2 and 3 of a block of 8-bit rows with the walks in SIMD lanes (row_lanes.hpp): what arm, YUYV frames
// and x86-64 CPUs without AVX2 take for GaussMl rows.
#include <algorithm>
#include <cstring>

#include "firmware/extract/stripe_stages.hpp"

namespace fs::fw::detail::stripe {

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

template void stage_lanes<1>(RowState<std::uint8_t>*, int, double, const ExtractParams&,
                             detail::GaussMlBatch&, detail::LaneWindow&);
template void stage_lanes<2>(RowState<std::uint8_t>*, int, double, const ExtractParams&,
                             detail::GaussMlBatch&, detail::LaneWindow&);

}  // namespace fs::fw::detail::stripe
