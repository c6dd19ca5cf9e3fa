// Stage 3's end: the FWHM and the sub-pixel centre of a row by each SubpixelMethod (CentreOfGravity,
// Gaussian3, GaussFit, GaussMl / GaussLog, BlaisRioux); GaussMl rows narrow enough for the batched fit go
// into a lane of the block's GaussMlBatch instead (defer_to_batch). Shared by the per-row, lane and mask
// walks.
#include <algorithm>
#include <array>
#include <cmath>

#include "firmware/extract/stripe_stages.hpp"

namespace fs::fw::detail::stripe {

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

template void centre_end<std::uint8_t, 1>(RowState<std::uint8_t>&, double, const ExtractParams&,
                                          detail::GaussMlBatch&, int, std::int64_t, std::int64_t,
                                          std::int64_t);
template void centre_end<std::uint8_t, 2>(RowState<std::uint8_t>&, double, const ExtractParams&,
                                          detail::GaussMlBatch&, int, std::int64_t, std::int64_t,
                                          std::int64_t);
template void centre_end<std::uint16_t, 1>(RowState<std::uint16_t>&, double, const ExtractParams&,
                                           detail::GaussMlBatch&, int, std::int64_t, std::int64_t,
                                           std::int64_t);

}  // namespace fs::fw::detail::stripe
