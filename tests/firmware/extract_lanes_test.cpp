// The walks of 8-bit rows in SIMD lanes (firmware/extract/row_lanes.hpp) and as bit masks (row_masks.hpp, what
// x86-64 CPUs with AVX2 take for contiguous rows) against the per-row walks
// (detail::extract_row_per_row_walks): the same status, centre, peak and width, bit for bit, on random rows
// (stripes anywhere including the row ends, narrow and wide, flat and saturated tops, second peaks, short rows,
// every method, other parameters) and on the scene renderer's frames, Mono8 and YUYV.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "firmware/extract/stripe_extractor.hpp"
#include "hw-sim/scene/scene.hpp"
#include "hw-sim/scene/stripe_renderer.hpp"
#include "support/test_paths.hpp"

namespace fs::fw {
namespace {

bool same(const RowPeak& a, const RowPeak& b) {
  return a.status == b.status && std::memcmp(&a.col, &b.col, sizeof a.col) == 0 &&
         std::memcmp(&a.peak, &b.peak, sizeof a.peak) == 0 && std::memcmp(&a.width, &b.width, sizeof a.width) == 0;
}

void add_stripe(std::vector<double>& v, double c, double s, double a) {
  for (std::size_t i = 0; i < v.size(); ++i) {
    const double x = (static_cast<double>(i) - c) / s;
    v[i] += a * std::exp(-0.5 * x * x);
  }
}

TEST(ExtractLanes, RandomRowsGiveThePerRowResults) {
  std::printf("walks of contiguous 8-bit rows: %s\n", detail::extract_walks_isa());
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> nd(0.0, 1.0);
  const SubpixelMethod methods[] = {SubpixelMethod::GaussMl, SubpixelMethod::CentreOfGravity,
                                    SubpixelMethod::Gaussian3, SubpixelMethod::BlaisRioux, SubpixelMethod::GaussFit};
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
      p.max_half_width = 1 + static_cast<std::uint32_t>(rng() % 30);
      p.saturation_run = static_cast<std::uint32_t>(rng() % 6);
      p.ambiguous_ratio = 0.2 + 0.6 * u(rng);
      p.min_contrast = 5.0 + 40.0 * u(rng);
    }
    const RowPeak want = detail::extract_row_per_row_walks(row.data(), n, 1, 255.0, p);
    const RowPeak got = extract_row<std::uint8_t>(row.data(), n, 1, 255.0, p);
    ASSERT_TRUE(same(got, want)) << "trial " << t << " status " << int(got.status) << " / " << int(want.status)
                                 << " col " << got.col << " / " << want.col << " width " << got.width << " / "
                                 << want.width;
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
        ASSERT_TRUE(same(extract_row<std::uint8_t>(row, w, 1, 255.0, p), want)) << "step " << step << " row " << y;
        ASSERT_TRUE(same(detail::extract_row_lane_walks(row, w, 1, 255.0, p), want)) << "lanes " << y;
        ok += want.status == RowStatus::Ok;
      }
    }
  }
  EXPECT_GT(ok, 3000);
}

}  // namespace
}  // namespace fs::fw
