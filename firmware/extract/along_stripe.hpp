#pragma once
// Edge-preserving refinement of a frame's stripe centres along the stripe (ExtractParams::along_stripe).
//
// On a planar face the laser stripe is locally a straight line in the image, so the per-row centres of
// neighbouring rows carry information about each other: a least-squares line through the centres of the
// rows i - h .. i + h (2h + 1 = along_stripe rows), evaluated at row i, has ~1 / (2h + 1) of the per-row
// variance when the per-row errors are independent. It must not smooth across what is not one line:
//   - only contiguous rows are used (a row without a point -- no stripe, rejected as ambiguous / saturated,
//     or cut off -- ends the window), and no step larger than kMaxStepPx between neighbouring rows;
//   - the line through the window must explain it: residual sum of squares <= the chi-square 99 % quantile
//     for its degrees of freedom times sigma^2, where sigma = the frame's per-row noise, estimated robustly
//     from the median residual of the frame's windows (along_stripe_scale), and the lines through its two
//     halves agree at row i (a kink in the stripe -- the corner between two faces -- inside the window shows
//     up as their difference);
//   - a window that fails falls back to the half on one side of row i (the side without the corner or step),
//     that one tested the same way, else the row keeps its own centre. So a row at a depth discontinuity, a
//     corner, or an outlier row is never moved by rows of another face.
// With hw-sim's default speckle, independent per pixel, the rows' errors are independent and the gain is the
// full ~sqrt(2h + 1) at most; a real laser's speckle is correlated over neighbouring pixels and rows, so the
// gain on hardware is smaller (hw-sim's RenderOptions::speckle_grain_px; tests/firmware/
// extract_along_stripe_test.cpp measures the gain at several grains). No
// allocation (fixed-size state on the stack); in place.
#include <cstdint>
#include <span>

#include "common/messages.hpp"

namespace fs::fw {

constexpr std::uint32_t kAlongStripeMaxRows = 15;  // along_stripe in {0, 1 (= off), 3, 5, ..., 15}

namespace detail {
constexpr double kMaxStepPx = 2.0;  // a larger column step between neighbouring rows ends the window
// refine_along_stripe with the portable build of the 15-row window, where refine_along_stripe takes its AVX2
// build on x86-64 CPUs that have AVX2: the same bits (the test that they agree).
void refine_along_stripe_portable(std::span<msg::StripePoint> pts, std::uint32_t rows, double sigma);
}  // namespace detail

// The per-row noise scale that refine_along_stripe's tests need, from the frame itself (robust: a median):
// the median residual of the least-squares lines through every whole window of `rows` rows (contiguous,
// joined rows), scaled to estimate sigma for independent Gaussian errors. It stays the right yardstick when
// neighbouring rows' errors are correlated, as a real laser's speckle makes them: a sigma from the median
// second difference of neighbouring centres (what the refinement used before) falls to about half there
// (second differences cancel correlated errors), and its tests then refused most windows (cube frames with a
// 1 px speckle grain: 0.0611 px refined with it, 0.0512 with this; independent speckle: 0.0258 and 0.0256). 0
// when fewer than 4 windows are sampled (every 4th of a run: ~16 whole windows).
double along_stripe_scale(std::span<const msg::StripePoint> pts, std::uint32_t rows);

// Refines pts[].col in place (points in row order, as extract_frame writes them). rows: the window (odd,
// 3..kAlongStripeMaxRows; 0 or 1 do nothing). sigma: the per-row noise (along_stripe_scale).
void refine_along_stripe(std::span<msg::StripePoint> pts, std::uint32_t rows, double sigma);

}  // namespace fs::fw
