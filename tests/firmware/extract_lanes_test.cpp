// The walks of 8-bit rows in SIMD lanes (firmware/extract/row_lanes.hpp) and as bit masks (row_masks.hpp,
// what x86-64 CPUs with AVX2 take for contiguous rows) against the per-row walks
// (detail::extract_row_per_row_walks): the same status, centre, peak and width, bit for bit, on random rows
// (stripes anywhere including the row ends, narrow and wide, flat and saturated tops, second peaks, short
// rows, every method, other parameters) and on the scene renderer's frames, Mono8 and YUYV.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "firmware/extract/row_scan.hpp"
#include "firmware/extract/stripe_extractor.hpp"
#include "hw-sim/scene/scene.hpp"
#include "hw-sim/scene/stripe_renderer.hpp"
#include "support/test_paths.hpp"

namespace fs::fw {
namespace {

bool same(const RowPeak& a, const RowPeak& b) {
  return a.status == b.status && std::memcmp(&a.col, &b.col, sizeof a.col) == 0 &&
         std::memcmp(&a.peak, &b.peak, sizeof a.peak) == 0 &&
         std::memcmp(&a.width, &b.width, sizeof a.width) == 0;
}

bool same_point(const msg::StripePoint& a, const msg::StripePoint& b) {
  return a.row == b.row && a.peak == b.peak && std::memcmp(&a.col, &b.col, sizeof a.col) == 0 &&
         std::memcmp(&a.width, &b.width, sizeof a.width) == 0;
}

void add_stripe(std::vector<double>& v, double c, double s, double a) {
  for (std::size_t i = 0; i < v.size(); ++i) {
    const double x = (static_cast<double>(i) - c) / s;
    v[i] += a * std::exp(-0.5 * x * x);
  }
}

TEST(ExtractLanes, RandomRowsGiveThePerRowResults) {
  std::printf("walks of contiguous 8-bit rows: %s\n", detail::extract_walks_isa());
#if defined(__x86_64__)
  // Every AVX2 CPU (Haswell, Excavator and later) has BMI1 and LZCNT: the mask walks must be what runs there.
  if (detail::cpu_has_avx2()) {
    EXPECT_STREQ(detail::extract_walks_isa(), "bit masks (avx2)");
  }
#endif
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> nd(0.0, 1.0);
  const SubpixelMethod methods[] = {SubpixelMethod::GaussMl, SubpixelMethod::CentreOfGravity,
                                    SubpixelMethod::Gaussian3, SubpixelMethod::BlaisRioux,
                                    SubpixelMethod::GaussFit};
  int status_seen[4] = {};
  for (int t = 0; t < 40000; ++t) {
    const std::uint32_t n = t % 5 == 0 ? 5 + static_cast<std::uint32_t>(rng() % 120) : 1280;
    std::vector<double> v(n, 5.0 + 60.0 * u(rng));
    const double c = u(rng) < 0.2 ? (u(rng) < 0.5 ? u(rng) * 6.0 : n - 1 - u(rng) * 6.0) : u(rng) * (n - 1);
    const double s = u(rng) < 0.1 ? 4.0 + 10.0 * u(rng) : 0.5 + 3.0 * u(rng);
    add_stripe(v, c, s, 300.0 * u(rng));
    if (u(rng) < 0.3) add_stripe(v, u(rng) * (n - 1), 0.5 + 3.0 * u(rng), 200.0 * u(rng));
    const double noise = 4.0 * u(rng);
    std::vector<std::uint8_t> row(n), yuyv(2 * n);
    for (std::uint32_t i = 0; i < n; ++i) {
      row[i] = static_cast<std::uint8_t>(std::clamp(std::lround(v[i] + noise * nd(rng)), 0L, 255L));
      yuyv[2 * i] = row[i];
      yuyv[2 * i + 1] = static_cast<std::uint8_t>(rng());
    }
    if (u(rng) < 0.05) std::fill(row.begin() + rng() % n, row.end(), row[0]);  // flat stretches
    ExtractParams p;
    // the batched methods take the lane walks, the others the per-row walks
    p.method = t % 2 ? (t % 4 == 1 ? SubpixelMethod::GaussMl : SubpixelMethod::GaussLog) : methods[t / 2 % 5];
    if (t % 7 == 0) {
      p.max_half_width = static_cast<std::uint32_t>(rng() % 31);  // 0 .. 30 (the lane and mask walks' range)
      p.saturation_run = static_cast<std::uint32_t>(rng() % 6);
      p.ambiguous_ratio = 0.2 + 0.6 * u(rng);
      p.min_contrast = t % 5 == 0 ? 0.0 : 5.0 + 40.0 * u(rng);
    }
    const RowPeak want = detail::extract_row_per_row_walks(row.data(), n, 1, 255.0, p);
    const RowPeak got = extract_row<std::uint8_t>(row.data(), n, 1, 255.0, p);
    ASSERT_TRUE(same(got, want)) << "trial " << t << " status " << int(got.status) << " / "
                                 << int(want.status) << " col " << got.col << " / " << want.col << " width "
                                 << got.width << " / " << want.width;
    const RowPeak lanes = detail::extract_row_lane_walks(row.data(), n, 1, 255.0, p);
    ASSERT_TRUE(same(lanes, want)) << "lane walks, trial " << t;
    ++status_seen[static_cast<int>(want.status)];
    if (t % 3 == 0) {
      const RowPeak want2 = detail::extract_row_per_row_walks(yuyv.data(), n, 2, 255.0, p);
      ASSERT_TRUE(same(extract_row<std::uint8_t>(yuyv.data(), n, 2, 255.0, p), want2)) << "yuyv trial " << t;
    }
  }
  for (int k = 0; k < 4; ++k) EXPECT_GT(status_seen[k], 100) << "status " << k;
}

// Whole frames through extract_frame (blocks of 8 rows, heights that are not multiples of 8, rows of every
// width around the 32 / 64-sample window and block sizes, peaks at the row ends, flat tops and flat rows, the
// walk parameters at their limits): the mask walks (where this CPU has them) and the lane walks give the
// per-row walks' points, bit for bit. Each frame in a buffer of its exact size (the sanitizer build sees any
// read past the last row).
TEST(ExtractLanes, RandomFramesGiveThePerRowResults) {
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> nd(0.0, 1.0);
  const std::uint32_t widths[] = {5, 31, 32, 33, 63, 64, 65, 100, 127, 128, 129, 640, 1280};
  const SubpixelMethod methods[] = {SubpixelMethod::GaussMl, SubpixelMethod::GaussLog,
                                    SubpixelMethod::CentreOfGravity};
  int rows_compared = 0, points = 0;
  for (int t = 0; t < 1500; ++t) {
    const std::uint32_t w = widths[rng() % std::size(widths)], h = 1 + static_cast<std::uint32_t>(rng() % 19);
    std::vector<std::uint8_t> img(static_cast<std::size_t>(w) * h);
    for (std::uint32_t y = 0; y < h; ++y) {
      std::vector<double> v(w, 5.0 + 60.0 * u(rng));
      const double c =
          u(rng) < 0.3 ? (u(rng) < 0.5 ? u(rng) * 40.0 : w - 1 - u(rng) * 40.0) : u(rng) * (w - 1);
      if (u(rng) < 0.9) add_stripe(v, std::clamp(c, 0.0, w - 1.0), 0.5 + 3.0 * u(rng), 300.0 * u(rng));
      if (u(rng) < 0.2) add_stripe(v, u(rng) * (w - 1), 0.5 + 3.0 * u(rng), 200.0 * u(rng));
      const double noise = 3.0 * u(rng);
      std::uint8_t* row = img.data() + static_cast<std::size_t>(y) * w;
      for (std::uint32_t i = 0; i < w; ++i)
        row[i] = static_cast<std::uint8_t>(std::clamp(std::lround(v[i] + noise * nd(rng)), 0L, 255L));
      if (u(rng) < 0.1) {  // a flat top up to 31 wide
        const std::uint32_t at = static_cast<std::uint32_t>(rng() % w),
                            len = 1 + static_cast<std::uint32_t>(rng() % 31);
        for (std::uint32_t i = at; i < std::min(w, at + len); ++i) row[i] = 250;
      }
      if (u(rng) < 0.03) std::fill(row, row + w, row[0]);  // a flat row
    }
    ExtractParams p;
    p.method = methods[t % 3];
    p.along_stripe = 0;
    if (t % 4 == 0) {
      p.max_half_width = static_cast<std::uint32_t>(rng() % 31);
      p.min_contrast = t % 8 == 0 ? 0.0 : 5.0 + 40.0 * u(rng);
      p.saturation_run = static_cast<std::uint32_t>(rng() % 6);
    }
    const FrameView f{img.data(), w, h, w, PixelFormat::Mono8, 0, 0, 0};
    std::vector<msg::StripePoint> want(h), best(h), lanes(h);
    const ExtractCounts cw = detail::extract_frame_walks(f, p, want, detail::Walks::Rows);
    const ExtractCounts cb = detail::extract_frame_walks(f, p, best, detail::Walks::Best);
    const ExtractCounts cl = detail::extract_frame_walks(f, p, lanes, detail::Walks::Lanes);
    ASSERT_EQ(cb.points, cw.points) << "trial " << t;
    ASSERT_EQ(cl.points, cw.points) << "trial " << t;
    ASSERT_EQ(cb.ambiguous, cw.ambiguous) << "trial " << t;
    ASSERT_EQ(cb.saturated, cw.saturated) << "trial " << t;
    ASSERT_EQ(cl.ambiguous, cw.ambiguous) << "trial " << t;
    for (std::uint32_t k = 0; k < cw.points; ++k) {  // field by field (the struct has padding)
      ASSERT_TRUE(same_point(best[k], want[k])) << "trial " << t << " point " << k;
      ASSERT_TRUE(same_point(lanes[k], want[k])) << "lanes, trial " << t << " point " << k;
    }
    rows_compared += static_cast<int>(h);
    points += static_cast<int>(cw.points);
  }
  EXPECT_GT(points, rows_compared / 2) << "most rows hold a stripe";
}

TEST(ExtractLanes, SceneFramesGiveThePerRowResults) {
  const sim::Scene scene = sim::load_scene(test::source_dir() / "hw-sim/scenes/cube.json");
  sim::StripeRenderer r(scene);
  const auto& cam = scene.calibration.camera;
  const std::uint32_t w = cam.width, h = cam.height;
  std::vector<std::uint8_t> img(static_cast<std::size_t>(w) * h);
  int ok = 0;
  for (double step : {30.0, 250.0, 470.0}) {
    r.render_step(step, 5, sim::FrameBuffer{img.data(), w, h, w, sim::FrameFormat::Mono8});
    for (auto m : {SubpixelMethod::GaussMl, SubpixelMethod::GaussLog, SubpixelMethod::CentreOfGravity}) {
      ExtractParams p;
      p.method = m;
      for (std::uint32_t y = 0; y < h; ++y) {
        const std::uint8_t* row = img.data() + std::size_t{y} * w;
        const RowPeak want = detail::extract_row_per_row_walks(row, w, 1, 255.0, p);
        ASSERT_TRUE(same(extract_row<std::uint8_t>(row, w, 1, 255.0, p), want))
            << "step " << step << " row " << y;
        ASSERT_TRUE(same(detail::extract_row_lane_walks(row, w, 1, 255.0, p), want)) << "lanes " << y;
        ok += want.status == RowStatus::Ok;
      }
    }
  }
  EXPECT_GT(ok, 3000);
}

}  // namespace
}  // namespace fs::fw
