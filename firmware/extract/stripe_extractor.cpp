#include "firmware/extract/stripe_extractor.hpp"

// The API (stripe_extractor.hpp): method names, extract_row, and the frame loop (extract_rows: the stages
// over blocks of rows, the batched fit, the points in row order) with the along-stripe refinement after it.
// The stages themselves: stripe_stages.hpp and the stripe_*.cpp files it names.
#include <algorithm>
#include <cstring>
#include <string>

#include "common/error.hpp"
#include "firmware/extract/along_stripe.hpp"
#include "firmware/extract/stripe_stages.hpp"

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

using namespace detail::stripe;  // the stages (stripe_stages.hpp)

// Which code a lane-path block of 8-bit rows takes: the bit-mask walks (stage_masks: contiguous rows on
// x86-64 CPUs with AVX2, BMI1 and LZCNT; detected once) or the lane walks (stage_lanes: YUYV, other CPUs and
// targets). Walks::Rows: the per-row walks (detail::extract_row_per_row_walks, the reference).
using Walks = detail::Walks;
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
    // frame's edge): the centre stays inside the row, as the per-row centres do (fuzz_extract_row covers it).
    const float last = static_cast<float>(f.width) - 0.5f;
    for (msg::StripePoint& pt : pts) pt.col = std::clamp(pt.col, -0.5f, last);
  }
  return c;
}

}  // namespace fs::fw
