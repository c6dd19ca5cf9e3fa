#pragma once
// Stripe extraction: one sub-pixel laser-stripe centre per image row.
//
// Per row: background = row mean, peak = row maximum. A row has a stripe when peak - background exceeds
// both min_contrast and nothing else in the row comes close (a second local maximum outside the peak's
// support above background + ambiguous_ratio * (peak - background) makes the row Ambiguous). A run of
// saturated pixels at the peak (>= saturation_run) makes the row Saturated. Rejected rows are flagged and
// produce no point. The sub-pixel centre is computed by the selected SubpixelMethod. The default is the
// maximum-likelihood Gaussian fit (GaussMl, gauss_ml.hpp), the most accurate on the scene renderer's speckled
// stripes (tests/firmware/extract_test.cpp and extract_scene_test.cpp compare the methods with each other and
// with the Cramer-Rao bound).
//
// Speed: one vectorized pass per row (row_scan.hpp: lane maxima per 64-sample block + the row sum), then
// scalar work only around the peak. extract_frame takes the rows in blocks of 8: each stage of the per-row
// work runs over the block before the next (the rows' latency chains overlap), and the GaussMl centres of
// the block are fitted together, one row per SIMD lane (gauss_ml.hpp, GaussMlBatch); for 8-bit GaussMl rows
// the walks around the peaks and the arithmetic between them run one row per lane too (row_lanes.hpp).
// extract_row runs the same code for one row and gives the same bits. No heap allocation: the caller provides
// the output span.
#include <cstdint>
#include <span>

#include "common/messages.hpp"
#include "firmware/device/camera.hpp"

namespace fs::fw {

// CentreOfGravity: window peak +- cog_half_window. Gaussian3: log-parabola through the 3 samples at the peak.
// BlaisRioux: zero crossing of the 4th-order derivative filter. GaussFit: weighted least-squares log-parabola
// (weights I^2, Guo's estimator) over every sample of the peak's support above 20 % of the contrast.
// GaussMl: maximum likelihood under the sensor noise model below (gauss_ml.hpp): unweighted log-parabola over
// the samples above 10 % of the contrast, then one Gauss-Newton step with weights 1 / var(signal).
// GaussLog: GaussMl's first step alone (the unweighted log-parabola over the samples above 10 % of the
// contrast: the maximum-likelihood fit when speckle is the only noise), about half the fit's cost.
enum class SubpixelMethod : std::uint8_t {
  CentreOfGravity = 0,
  Gaussian3 = 1,
  BlaisRioux = 2,
  GaussFit = 3,
  GaussMl = 4,
  GaussLog = 5
};
const char* to_string(SubpixelMethod m);
// Parses "cog" | "gauss3" | "blais-rioux" | "gauss-fit" | "gauss-ml" | "gauss-log"; throws fs::Error
// otherwise.
SubpixelMethod parse_subpixel_method(const char* text);

enum class RowStatus : std::uint8_t { Ok = 0, NoStripe = 1, Ambiguous = 2, Saturated = 3 };

struct ExtractParams {
  SubpixelMethod method = SubpixelMethod::GaussMl;
  double min_contrast = 24.0;         // peak - background, in 8-bit units (scaled by 257 for Mono16)
  double ambiguous_ratio = 0.5;       // second peak above bg + ratio * (peak - bg) -> Ambiguous
  std::uint32_t saturation_run = 3;   // this many pixels at full scale around the peak -> Saturated
  std::uint32_t cog_half_window = 5;  // centre-of-gravity window: peak +- this many pixels
  std::uint32_t max_half_width = 24;  // support of the peak searched at most this far each side
  // Sensor noise model for GaussMl's weights, in 8-bit DN (the bench camera's, = the hw-sim camera twin's):
  // per-pixel variance = read_noise^2 + 1/12 + shot_noise^2 * S + (speckle * S)^2 for a signal S. The weights
  // depend on the model only mildly, so a rough characterization of the sensor is enough
  // (tests/firmware/extract_test.cpp compares the default model with one matched to the rows' noise).
  double read_noise = 1.5;
  double shot_noise = 0.35;
  double speckle = 0.12;
  // Along-stripe refinement (along_stripe.hpp): each row's centre from a robust line fit over this many
  // neighbouring rows (odd, 3..15) of the same straight stretch of stripe, in extract_frame; 0 or 1 = off,
  // the per-row centres (what extract_row gives).
  std::uint32_t along_stripe = 15;
  // Software prefetch: while a row is passed, the row this many rows below it is requested from memory (every
  // cache line of it), so that a frame a camera wrote to memory arrives in the cache before the pass reaches
  // it (the hardware prefetchers follow only the pass itself, which is idle while the rows' centres are
  // fitted). 0 = off. 16 rows = two blocks of rows ahead. bench_extract --benchmark_filter=StreamVsMemcpy
  // measures a frame from memory, --benchmark_filter=ExtractVsMemcpy a frame already in the caches.
  std::uint32_t prefetch_rows = 16;
};

struct ExtractCounts {
  std::uint32_t rows = 0, points = 0, no_stripe = 0, ambiguous = 0, saturated = 0;
  // msg::StripeHeader::flags bits: 1 = saturated rows present, 2 = ambiguous rows present.
  std::uint32_t header_flags() const { return (saturated ? 1u : 0u) | (ambiguous ? 2u : 0u); }
};

// One row's result (exposed for tests and the accuracy study).
struct RowPeak {
  RowStatus status = RowStatus::NoStripe;
  double col = 0.0;
  double peak = 0.0;
  double width = 0.0;
};

// Analyses one row of `n` samples of type T (uint8_t or uint16_t) spaced `step` samples apart.
template <typename T>
RowPeak extract_row(const T* row, std::uint32_t n, std::uint32_t step, double full_scale,
                    const ExtractParams& p);

namespace detail {
// extract_row for 8-bit rows with the per-row walks that Mono16 rows take, instead of the walks of a block's
// rows in SIMD lanes (row_lanes.hpp) that 8-bit rows take: the reference that tests compare the lane path
// with.
RowPeak extract_row_per_row_walks(const std::uint8_t* row, std::uint32_t n, std::uint32_t step,
                                  double full_scale, const ExtractParams& p);
// extract_row with the walks of a block's rows in SIMD lanes (row_lanes.hpp) where extract_row takes the
// bit-mask walks (row_masks.hpp: contiguous 8-bit rows on x86-64 with AVX2); the same results.
RowPeak extract_row_lane_walks(const std::uint8_t* row, std::uint32_t n, std::uint32_t step,
                               double full_scale, const ExtractParams& p);
// Which walks extract_row and extract_frame take for contiguous 8-bit rows here: "bit masks (avx2)" or
// "lanes".
const char* extract_walks_isa();
// The walks of 8-bit rows: Best (what extract_row and extract_frame take), Lanes (the SIMD-lane walks, what
// arm and CPUs without AVX2 take) or Rows (the per-row walks).
enum class Walks { Best, Lanes, Rows };
}  // namespace detail

// Extracts every row of the frame into `out` (at most out.size() points, rows in order), then refines the
// centres along the stripe when params.along_stripe >= 3. Returns the counts.
ExtractCounts extract_frame(const FrameView& frame, const ExtractParams& params,
                            std::span<msg::StripePoint> out);

namespace detail {
// extract_frame with the walks chosen; every choice gives the same results
// (tests/firmware/extract_lanes_test.cpp).
ExtractCounts extract_frame_walks(const FrameView& frame, const ExtractParams& params,
                                  std::span<msg::StripePoint> out, Walks walks);
// The first byte of the row `rows` below row y of the frame, which extract_frame prefetches while it passes
// row y (ExtractParams::prefetch_rows); null when rows is 0 or that row is past the frame's last (y <
// frame.height).
const std::uint8_t* prefetch_target(const FrameView& frame, std::uint32_t y, std::uint32_t rows);
}  // namespace detail

}  // namespace fs::fw
