// Stripe extraction on synthetic Gaussian rows with known centres: status flags, accuracy of each sub-pixel
// method (error vs. noise table printed), Mono8 / Mono16 / YUYV frames.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "common/error.hpp"
#include "firmware/extract/stripe_extractor.hpp"

namespace fs::fw {
namespace {

// A stripe row: ambient + amplitude * exp(-(x-c)^2 / (2 s^2)) integrated over each pixel, + Gaussian noise.
std::vector<std::uint8_t> gaussian_row(std::uint32_t n, double centre, double sigma, double amplitude,
                                       double ambient, double noise, std::mt19937& rng) {
  std::normal_distribution<double> nd(0.0, 1.0);
  std::vector<std::uint8_t> row(n);
  for (std::uint32_t i = 0; i < n; ++i) {
    const double x0 = (static_cast<double>(i) - 0.5 - centre) / (sigma * std::sqrt(2.0));
    const double x1 = (static_cast<double>(i) + 0.5 - centre) / (sigma * std::sqrt(2.0));
    const double area = 0.5 * (std::erf(x1) - std::erf(x0)) * sigma * std::sqrt(2.0 * M_PI);
    double v = ambient + amplitude * area;
    v += noise * nd(rng);
    row[i] = static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
  }
  return row;
}

// matched_model: GaussMl's sensor noise model set to these rows' noise (additive only) instead of the default
// (the hw-sim camera's, dominated by 12 % speckle).
double mean_abs_error(SubpixelMethod m, double noise, int trials, std::uint32_t seed,
                      bool matched_model = false) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uc(100.0, 500.0), us(1.2, 2.5);
  ExtractParams p;
  p.method = m;
  if (matched_model) {
    p.read_noise = noise;
    p.shot_noise = 0.0;
    p.speckle = 0.0;
  }
  double sum = 0.0;
  int n = 0;
  for (int t = 0; t < trials; ++t) {
    const double c = uc(rng);
    const auto row = gaussian_row(640, c, us(rng), 180.0, 20.0, noise, rng);
    const RowPeak r = extract_row<std::uint8_t>(row.data(), 640, 1, 255.0, p);
    if (r.status != RowStatus::Ok) continue;
    sum += std::abs(r.col - c);
    ++n;
  }
  EXPECT_GT(n, trials * 9 / 10);
  return n ? sum / n : 1e9;
}

TEST(Extract, FindsCentreWithoutNoise) {
  std::mt19937 rng(1);
  const auto row = gaussian_row(320, 123.37, 1.8, 200.0, 15.0, 0.0, rng);
  for (auto m : {SubpixelMethod::CentreOfGravity, SubpixelMethod::Gaussian3, SubpixelMethod::BlaisRioux,
                 SubpixelMethod::GaussFit, SubpixelMethod::GaussMl}) {
    ExtractParams p;
    p.method = m;
    const RowPeak r = extract_row<std::uint8_t>(row.data(), 320, 1, 255.0, p);
    ASSERT_EQ(r.status, RowStatus::Ok) << to_string(m);
    EXPECT_NEAR(r.col, 123.37, 0.05) << to_string(m);
    EXPECT_NEAR(r.width, 2.3548 * 1.8, 0.5) << to_string(m);  // FWHM of the Gaussian
    EXPECT_GE(r.peak, 200.0);
  }
}

TEST(Extract, DefaultMethodMeetsAccuracyAtDefaultNoise) {
  // Default noise of the sim camera: sigma 2 DN. Requirement: mean absolute error <= 0.05 px.
  EXPECT_LE(mean_abs_error(ExtractParams{}.method, 2.0, 2000, 7), 0.05);
}

TEST(Extract, ErrorVersusNoiseTable) {
  std::printf(
      "noise_dn  cog      gauss3   blais-rioux  gauss-fit  gauss-ml  gauss-ml(matched model)  (mean |error| "
      "px, 2000 rows each)\n");
  double prev_gauss = 0.0;
  for (double noise : {0.0, 1.0, 2.0, 4.0, 8.0}) {
    const double cog = mean_abs_error(SubpixelMethod::CentreOfGravity, noise, 2000, 11);
    const double g3 = mean_abs_error(SubpixelMethod::Gaussian3, noise, 2000, 11);
    const double br = mean_abs_error(SubpixelMethod::BlaisRioux, noise, 2000, 11);
    const double gf = mean_abs_error(SubpixelMethod::GaussFit, noise, 2000, 11);
    const double ml = mean_abs_error(SubpixelMethod::GaussMl, noise, 2000, 11);
    const double mm = mean_abs_error(SubpixelMethod::GaussMl, noise, 2000, 11, true);
    std::printf("%8.1f  %.4f   %.4f   %.4f       %.4f     %.4f    %.4f\n", noise, cog, g3, br, gf, ml, mm);
    // With the right noise model the ML fit is at least as good as the intensity-weighted fit (5 % slack).
    if (noise > 0.0) {
      EXPECT_LE(mm, gf * 1.05 + 1e-3) << noise;
    }
    EXPECT_GE(g3 + 1e-3, prev_gauss * 0.5);  // error grows (roughly) with noise
    prev_gauss = g3;
  }
}

TEST(Extract, RejectsRowWithoutStripe) {
  std::mt19937 rng(2);
  std::vector<std::uint8_t> row(400);
  std::normal_distribution<double> nd(30.0, 3.0);
  for (auto& v : row) v = static_cast<std::uint8_t>(std::clamp(std::lround(nd(rng)), 0L, 255L));
  EXPECT_EQ(extract_row<std::uint8_t>(row.data(), 400, 1, 255.0, ExtractParams{}).status,
            RowStatus::NoStripe);
}

TEST(Extract, FlagsDoublePeakAsAmbiguous) {
  std::mt19937 rng(3);
  auto a = gaussian_row(400, 100.0, 1.5, 180.0, 20.0, 0.0, rng);
  const auto b = gaussian_row(400, 260.0, 1.5, 150.0, 0.0, 0.0, rng);  // a reflection, 83 % as bright
  for (std::size_t i = 0; i < a.size(); ++i) a[i] = static_cast<std::uint8_t>(std::min(255, a[i] + b[i]));
  EXPECT_EQ(extract_row<std::uint8_t>(a.data(), 400, 1, 255.0, ExtractParams{}).status, RowStatus::Ambiguous);
  // A weak reflection (20 %) is tolerated and the main stripe is found.
  auto c = gaussian_row(400, 100.0, 1.5, 180.0, 20.0, 0.0, rng);
  const auto d = gaussian_row(400, 260.0, 1.5, 36.0, 0.0, 0.0, rng);
  for (std::size_t i = 0; i < c.size(); ++i) c[i] = static_cast<std::uint8_t>(std::min(255, c[i] + d[i]));
  const RowPeak r = extract_row<std::uint8_t>(c.data(), 400, 1, 255.0, ExtractParams{});
  ASSERT_EQ(r.status, RowStatus::Ok);
  EXPECT_NEAR(r.col, 100.0, 0.05);
}

TEST(Extract, FlagsSaturationPlateau) {
  std::mt19937 rng(4);
  const auto row = gaussian_row(400, 200.0, 3.0, 900.0, 20.0, 0.0, rng);  // clipped at 255 over many pixels
  EXPECT_EQ(extract_row<std::uint8_t>(row.data(), 400, 1, 255.0, ExtractParams{}).status,
            RowStatus::Saturated);
}

TEST(Extract, TwoClippedSamplesStillGiveTheCentre) {
  // A narrow stripe clipped on its two top samples (below saturation_run): the ML fit leaves clipped samples
  // out; too few remain, so it falls back to the support's centre of gravity, which is symmetric here.
  std::mt19937 rng(6);
  const auto row = gaussian_row(300, 150.5, 0.9, 320.0, 20.0, 0.0, rng);
  ASSERT_EQ(row[150], 255);
  ASSERT_EQ(row[151], 255);
  ASSERT_LT(row[149], 255);
  for (auto m : {SubpixelMethod::GaussMl, SubpixelMethod::GaussFit, SubpixelMethod::CentreOfGravity}) {
    ExtractParams p;
    p.method = m;
    const RowPeak r = extract_row<std::uint8_t>(row.data(), 300, 1, 255.0, p);
    ASSERT_EQ(r.status, RowStatus::Ok) << to_string(m);
    EXPECT_NEAR(r.col, 150.5, 0.1) << to_string(m);
  }
}

TEST(Extract, CentreStaysInsideTheRowAtItsEdges) {
  std::mt19937 rng(8);
  for (double c : {0.3, 1.0, 1.7, 318.4, 319.0}) {
    const auto row = gaussian_row(320, c, 1.5, 180.0, 15.0, 2.0, rng);
    for (auto m : {SubpixelMethod::CentreOfGravity, SubpixelMethod::Gaussian3, SubpixelMethod::BlaisRioux,
                   SubpixelMethod::GaussFit, SubpixelMethod::GaussMl}) {
      ExtractParams p;
      p.method = m;
      const RowPeak r = extract_row<std::uint8_t>(row.data(), 320, 1, 255.0, p);
      if (r.status != RowStatus::Ok) continue;
      EXPECT_GE(r.col, -0.5) << to_string(m) << " " << c;
      EXPECT_LE(r.col, 319.5) << to_string(m) << " " << c;
      EXPECT_NEAR(r.col, c, 1.0) << to_string(m) << " " << c;
    }
  }
}

// A stripe with a shoulder above half maximum that reaches exactly one sample past the support's bound
// (max_half_width = 24 samples right of the peak): the half-maximum walk stops at the bound, not on a flank,
// so the FWHM keeps the bound there instead of interpolating towards the next shoulder sample (which,
// alternating by 3 DN, extrapolated by up to ~17 px either way: the fuzzer found widths of -4500 px on such
// Mono16 rows). Every method and walk path, 8 and 16 bit.
TEST(Extract, FwhmStaysInsideASupportCutByMaxHalfWidth) {
  std::vector<std::uint8_t> row(100, 10);
  row[39] = 60;
  row[40] = 250;  // the peak
  for (int i = 41; i <= 65; ++i)
    row[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(180 + (i % 2) * 3);
  std::vector<std::uint16_t> row16(row.size());
  for (std::size_t i = 0; i < row.size(); ++i) row16[i] = static_cast<std::uint16_t>(row[i] * 257);
  for (auto m : {SubpixelMethod::GaussMl, SubpixelMethod::GaussLog, SubpixelMethod::CentreOfGravity,
                 SubpixelMethod::GaussFit, SubpixelMethod::Gaussian3, SubpixelMethod::BlaisRioux}) {
    ExtractParams p;
    p.method = m;
    const RowPeak results[] = {extract_row<std::uint8_t>(row.data(), 100, 1, 255.0, p),
                               detail::extract_row_lane_walks(row.data(), 100, 1, 255.0, p),
                               detail::extract_row_per_row_walks(row.data(), 100, 1, 255.0, p),
                               extract_row<std::uint16_t>(row16.data(), 100, 1, 65535.0, p)};
    for (const RowPeak& r : results) {
      ASSERT_EQ(r.status, RowStatus::Ok) << to_string(m);
      // left edge interpolated between samples 38 and 40, right edge = the bound at 40 + 24
      EXPECT_GE(r.width, 24.0) << to_string(m);
      EXPECT_LE(r.width, 26.0) << to_string(m);
      EXPECT_GE(r.col, 39.5) << to_string(m);
      EXPECT_LE(r.col, 64.5) << to_string(m);
    }
  }
}

TEST(Extract, FrameFormatsAgree) {
  std::mt19937 rng(5);
  const std::uint32_t w = 256, h = 8;
  std::vector<std::uint8_t> mono8(w * h), yuyv(w * h * 2);
  std::vector<std::uint16_t> mono16(w * h);
  for (std::uint32_t y = 0; y < h; ++y) {
    const auto row = gaussian_row(w, 40.0 + 20.0 * y + 0.25 * y, 1.6, 170.0, 10.0, 0.0, rng);
    for (std::uint32_t x = 0; x < w; ++x) {
      mono8[y * w + x] = row[x];
      mono16[y * w + x] = static_cast<std::uint16_t>(row[x] * 257);
      yuyv[(y * w + x) * 2] = row[x];
      yuyv[(y * w + x) * 2 + 1] = 128;
    }
  }
  // Row 3 without stripe.
  for (std::uint32_t x = 0; x < w; ++x) {
    mono8[3 * w + x] = 10;
    mono16[3 * w + x] = 2570;
    yuyv[(3 * w + x) * 2] = 10;
  }
  std::vector<msg::StripePoint> out8(h), out16(h), outy(h);
  FrameView f8{mono8.data(), w, h, w, PixelFormat::Mono8, 0, 0, 0};
  FrameView f16{
      reinterpret_cast<const std::uint8_t*>(mono16.data()), w, h, w * 2, PixelFormat::Mono16, 0, 0, 0};
  FrameView fy{yuyv.data(), w, h, w * 2, PixelFormat::Yuyv, 0, 0, 0};
  const auto c8 = extract_frame(f8, ExtractParams{}, out8);
  const auto c16 = extract_frame(f16, ExtractParams{}, out16);
  const auto cy = extract_frame(fy, ExtractParams{}, outy);
  EXPECT_EQ(c8.points, h - 1);
  EXPECT_EQ(c8.no_stripe, 1u);
  EXPECT_EQ(c16.points, h - 1);
  EXPECT_EQ(cy.points, h - 1);
  for (std::uint32_t i = 0; i < c8.points; ++i) {
    const std::uint32_t y = out8[i].row;
    EXPECT_NEAR(out8[i].col, 40.0 + 20.0 * y + 0.25 * y, 0.05);
    EXPECT_NEAR(out16[i].col, out8[i].col, 1e-3);
    EXPECT_NEAR(outy[i].col, out8[i].col, 1e-3);
    EXPECT_GT(out16[i].peak, 40000);
  }
  // Output capacity is respected.
  std::vector<msg::StripePoint> small(2);
  EXPECT_EQ(extract_frame(f8, ExtractParams{}, small).points, 2u);
}

// Where extract_frame prefetches (ExtractParams::prefetch_rows rows below the row it passes): that row's
// first byte while it is in the frame, else nothing, at every distance up to the type's limit (no
// wrap-around).
TEST(Extract, PrefetchTargetsTheRowAheadInsideTheFrame) {
  std::vector<std::uint8_t> buf(124 * 37);
  const FrameView f{buf.data(), 100, 37, 124, PixelFormat::Mono8, 0, 0, 0};
  EXPECT_EQ(detail::prefetch_target(f, 0, 16), buf.data() + 16 * 124);
  EXPECT_EQ(detail::prefetch_target(f, 20, 16), buf.data() + 36 * 124);  // the last row
  EXPECT_EQ(detail::prefetch_target(f, 21, 16), nullptr);
  EXPECT_EQ(detail::prefetch_target(f, 0, 36), buf.data() + 36 * 124);
  EXPECT_EQ(detail::prefetch_target(f, 0, 37), nullptr);
  EXPECT_EQ(detail::prefetch_target(f, 36, 1), nullptr);
  EXPECT_EQ(detail::prefetch_target(f, 5, 0), nullptr);  // off
  EXPECT_EQ(detail::prefetch_target(f, 5, 0xffffffffu), nullptr);
  EXPECT_EQ(detail::prefetch_target(f, 0xfffffff0u, 32), nullptr);  // a row past the frame: nothing
}

// ExtractParams::prefetch_rows only asks the caches for rows ahead: the same points, bit for bit, at every
// distance (up to and past the frame's height, where no row is prefetched), in every format and with padded
// strides.
TEST(Extract, PrefetchLeavesThePointsAsTheyAre) {
  std::mt19937 rng(11);
  const std::uint32_t w = 200, h = 37, pad = 24;
  std::vector<std::uint8_t> mono8((w + pad) * h), yuyv((2 * w + pad) * h);
  std::vector<std::uint16_t> mono16((w + pad) * h);
  for (std::uint32_t y = 0; y < h; ++y) {
    const auto row = gaussian_row(w, 30.0 + 3.7 * y, 1.5, 160.0, 12.0, 2.0, rng);
    for (std::uint32_t x = 0; x < w; ++x) {
      mono8[y * (w + pad) + x] = row[x];
      mono16[y * (w + pad) + x] = static_cast<std::uint16_t>(row[x] * 257);
      yuyv[y * (2 * w + pad) + 2 * x] = row[x];
      yuyv[y * (2 * w + pad) + 2 * x + 1] = 128;
    }
  }
  const FrameView frames[] = {{mono8.data(), w, h, w + pad, PixelFormat::Mono8, 0, 0, 0},
                              {reinterpret_cast<const std::uint8_t*>(mono16.data()), w, h, 2 * (w + pad),
                               PixelFormat::Mono16, 0, 0, 0},
                              {yuyv.data(), w, h, 2 * w + pad, PixelFormat::Yuyv, 0, 0, 0}};
  for (const FrameView& f : frames) {
    ExtractParams off;
    off.prefetch_rows = 0;
    std::vector<msg::StripePoint> ref(h);
    const ExtractCounts rc = extract_frame(f, off, ref);
    ASSERT_GT(rc.points, h - 3);
    for (const std::uint32_t d : {1u, 7u, 16u, h - 1, h, h + 1, 1000u, 0xffffffffu}) {
      ExtractParams p;
      p.prefetch_rows = d;
      std::vector<msg::StripePoint> out(h);
      const ExtractCounts c = extract_frame(f, p, out);
      ASSERT_EQ(c.points, rc.points) << "prefetch_rows " << d;
      for (std::uint32_t i = 0; i < c.points; ++i) {  // field by field (the padding is not the points')
        const std::string at = "prefetch_rows " + std::to_string(d) + ", format " +
                               std::to_string(static_cast<int>(f.format)) + ", point " + std::to_string(i);
        EXPECT_EQ(out[i].row, ref[i].row) << at;
        EXPECT_EQ(std::bit_cast<std::uint32_t>(out[i].col), std::bit_cast<std::uint32_t>(ref[i].col)) << at;
        EXPECT_EQ(out[i].peak, ref[i].peak) << at;
        EXPECT_EQ(std::bit_cast<std::uint32_t>(out[i].width), std::bit_cast<std::uint32_t>(ref[i].width))
            << at;
      }
    }
  }
}

TEST(Extract, ParsesMethodNames) {
  EXPECT_EQ(parse_subpixel_method("cog"), SubpixelMethod::CentreOfGravity);
  EXPECT_EQ(parse_subpixel_method("blais-rioux"), SubpixelMethod::BlaisRioux);
  EXPECT_EQ(parse_subpixel_method("gauss-fit"), SubpixelMethod::GaussFit);
  EXPECT_EQ(parse_subpixel_method("gauss-ml"), SubpixelMethod::GaussMl);
  EXPECT_STREQ(to_string(SubpixelMethod::GaussMl), "gauss-ml");
  EXPECT_EQ(parse_subpixel_method("gauss-log"), SubpixelMethod::GaussLog);
  EXPECT_STREQ(to_string(SubpixelMethod::GaussLog), "gauss-log");
  EXPECT_THROW(parse_subpixel_method("fft"), fs::Error);
}

}  // namespace
}  // namespace fs::fw
