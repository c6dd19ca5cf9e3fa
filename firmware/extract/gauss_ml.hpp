#pragma once
// Maximum-likelihood Gaussian centre of a stripe profile under the sensor noise model (the default sub-pixel
// method, SubpixelMethod::GaussMl).
//
// The profile y(x) = A exp(-(x - u)^2 / (2 s^2)) is observed with independent per-pixel noise of variance
//   var(S) = read^2 + 1/12 + shot^2 S + speckle^2 S^2        (S = signal above background, 8-bit DN)
// (read noise, quantization, shot noise, multiplicative laser speckle). Speckle dominates on the stripe, so
// the information about u sits in the flanks as much as at the top; weighting by intensity (GaussFit)
// throws most of it away. Two steps, both closed form:
//   1. unweighted least squares of ln y = a + b x + c x^2 over the contiguous samples above 10 % of the
//      contrast (this is already the ML fit when speckle alone is present);
//   2. one Gauss-Newton step of the weighted least squares in the intensity domain, weights 1 / var(S(x))
//   from
//      that model, over |x - u| <= 3 s.
// Speed: gauss_ml_centre (one row): the per-sample work (log, exp, weights, the moment sums) is branch-free
// float arithmetic over chunks of kChunk samples with one accumulator per lane, which the compiler vectorizes
// (SSE2/AVX2/NEON); the 3x3 solves are in double. gauss_ml_centre_batch (below, what extraction uses) fits 8
// rows at once with the rows in the SIMD lanes, in a portable (SSE2), an AVX2 and an AVX-512VL build, each
// cheaper per row than the one-row fit (bench_extract --benchmark_filter=GaussMlBatch).
// On the scene renderer's stripes this comes close to the Cramer-Rao bound (tests/firmware/
// extract_scene_test.cpp prints both and checks the efficiency). Samples at full scale are censored (left out
// of both steps).
#include <cstdint>

namespace fs::fw::detail {

struct SensorNoise {
  double read = 1.5;      // read noise sigma, DN
  double shot = 0.35;     // shot noise sigma = shot * sqrt(S), DN
  double speckle = 0.12;  // relative sigma of the speckle
};

constexpr int kChunk = 8;

// y[0..n): samples minus background in 8-bit DN; y[k] >= clip marks a sample at full scale. y must hold
// n + kChunk floats (the tail is read, masked out, never used: fill it with anything finite, e.g. 0). `ic` is
// the index of the peak sample, `contrast` the peak's height above background (DN). On success returns true
// and sets `centre` (in index units of y, e.g. ic + 0.31); false when no Gaussian fits (caller falls back).
// intensity_step = false stops after step 1 (SubpixelMethod::GaussLog: the unweighted log-parabola, the ML
// fit under speckle alone; the same sample set and the same fallbacks).
bool gauss_ml_centre(const float* y, int n, int ic, double contrast, double clip, const SensorNoise& noise,
                     double& centre, bool intensity_step = true);

// The Cramer-Rao lower bound on the variance of any unbiased estimate of u (px^2) for a stripe of peak A (DN
// above background) and sigma s (px) centred at u on integer pixels, with A and s unknown too (Fisher
// information of the Gaussian likelihood with signal-dependent variance, 3x3, inverted). Pixels at full scale
// (background + A >= full_scale_dn) carry no information. For the accuracy study and its tests.
double centre_crb(double u, double s, double A, double background, double full_scale_dn,
                  const SensorNoise& noise);

// The same fit for kBatch rows at once, the rows in SIMD lanes (stripe_extractor.cpp's extract_frame fills
// one lane per row of a block of rows). Every per-sample loop runs over the lanes with a fixed trip count, so
// it vectorizes across rows (the walks that bound the fit become lane-wise masks, no per-row branches); the
// 3x3 solves are lane loops in double too. Each lane's window is the samples at ic + x for x in [xa, xb],
// -kBatchHalf < xa <= 0 <= xb < kBatchHalf, stored at y[kBatchHalf + x][lane]. Per lane the result is the one
// gauss_ml_centre gives on that window up to float rounding (the sums are added in another order): same
// sample sets, same fallbacks. It depends on that lane's inputs only, bit for bit (unused lanes and the other
// lanes' windows only add exact zeros), so one row fitted alone and in a batch give the same centre.
constexpr int kBatch = 8;
constexpr int kBatchHalf = 16;

struct GaussMlBatch {
  alignas(64) float y[2 * kBatchHalf][kBatch] = {};  // samples minus background, 8-bit DN; finite everywhere
  alignas(32) std::int32_t xa[kBatch] = {};          // the lane's window (relative to its ic)
  alignas(32) std::int32_t xb[kBatch] = {};
  alignas(32) double contrast[kBatch] = {};  // peak height above background, DN
  alignas(32) double clip[kBatch] = {};      // samples >= clip are at full scale (censored)
  bool intensity_step = true;                // false: step 1 only (GaussLog), see gauss_ml_centre
  // Results: ok[lane] != 0 when a Gaussian fits; then centre[lane] is the centre relative to ic.
  alignas(32) double centre[kBatch] = {};
  alignas(32) std::int32_t ok[kBatch] = {};
};

// Fits every lane (set unused lanes' xa = xb = 0; their results mean nothing). With the best instruction set
// of this CPU (on x86-64 AVX-512VL or AVX2 when present, chosen once at run time; else the portable build of
// the same code: 4 lanes at a time, SSE2 / NEON). All builds give the same bits (no FMA contraction).
void gauss_ml_centre_batch(GaussMlBatch& b, const SensorNoise& noise);
// The portable build alone and the AVX2 build alone (false, nothing done, where the CPU has no AVX2 or the
// target is not x86-64), for the test that all builds agree bit for bit and the benchmark; and which build
// gauss_ml_centre_batch uses.
void gauss_ml_centre_batch_portable(GaussMlBatch& b, const SensorNoise& noise);
bool gauss_ml_centre_batch_avx2(GaussMlBatch& b, const SensorNoise& noise);
const char* gauss_ml_batch_isa();

}  // namespace fs::fw::detail
