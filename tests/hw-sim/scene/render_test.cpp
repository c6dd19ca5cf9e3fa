// Stripe renderer: profile centroid vs ground truth, determinism, noise, width/intensity model, no
// allocation.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <vector>

#include "common/error.hpp"
#include "hw-sim/scene/stripe_renderer.hpp"
#include "support/test_paths.hpp"

// Counts heap allocations while g_counting is set (this test binary's global operator new).
namespace {
std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};
}  // namespace
// The replacements pair malloc with free by design; GCC cannot see that new and delete are both replaced.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void* operator new(std::size_t n) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace {

using fs::sim::FrameBuffer;
using fs::sim::FrameFormat;

fs::sim::Scene load(const char* name) {
  return fs::sim::load_scene(fs::test::source_dir() / "hw-sim/scenes" / (std::string(name) + ".json"));
}

struct Frame {
  std::vector<std::uint16_t> storage;
  FrameBuffer fb;
  Frame(const fs::sim::Scene& s, FrameFormat f, std::uint32_t pad = 0) {
    const auto& cam = s.calibration.camera;
    const std::uint32_t bpp = f == FrameFormat::Mono16 ? 2 : 1;
    fb.width = cam.width;
    fb.height = cam.height;
    fb.stride = cam.width * bpp + pad;
    fb.format = f;
    storage.assign((static_cast<std::size_t>(fb.stride) * cam.height + 1) / 2, 0);
    fb.data = reinterpret_cast<std::uint8_t*>(storage.data());
  }
  double at(std::uint32_t r, std::uint32_t x) const {
    const std::uint8_t* row = fb.data + static_cast<std::size_t>(r) * fb.stride;
    if (fb.format == FrameFormat::Mono16) return reinterpret_cast<const std::uint16_t*>(row)[x];
    return row[x];
  }
};

// Centroid of (pixel - ambient) in the stripe's +-5 sigma window, noise-free: must match the true centre.
// Mono8 rounds every pixel to 1 DN: dim stripes are limited by that quantization, so only stripes with a
// peak of at least `min_peak` DN count (Mono16: 1/257 DN steps, every stripe).
void check_centroids(const char* scene_name, FrameFormat format, double max_err, float min_peak) {
  const auto s = load(scene_name);
  fs::sim::RenderOptions opt;
  opt.noise_scale = 0.0;
  fs::sim::StripeRenderer r(s, opt);
  Frame f(s, format, 16);
  const double scale = format == FrameFormat::Mono16 ? 257.0 : 1.0;
  std::size_t rows = 0;
  double worst = 0.0;
  for (double step : {40.0, 130.5, 250.0, 333.0, 460.0}) {
    r.render_step(step, 1, f.fb);
    for (std::uint32_t row = 0; row < f.fb.height; ++row) {
      const auto& t = r.truth()[row];
      const double sig = r.sigma_px()[row];
      if (!t.valid() || r.peak()[row] < min_peak || sig > 6.0) continue;
      const int x0 = static_cast<int>(std::floor(t.column - 5 * sig)),
                x1 = static_cast<int>(std::ceil(t.column + 5 * sig));
      if (x0 < 0 || x1 >= static_cast<int>(f.fb.width)) continue;
      double sw = 0.0, swx = 0.0;
      for (int x = x0; x <= x1; ++x) {
        const double w = f.at(row, static_cast<std::uint32_t>(x)) - opt.ambient * scale;
        sw += w;
        swx += w * x;
      }
      ASSERT_GT(sw, 0.0);
      const double err = std::abs(swx / sw - t.column);
      worst = std::max(worst, err);
      EXPECT_LT(err, max_err) << scene_name << " step " << step << " row " << row << " sigma " << sig;
      ++rows;
    }
  }
  EXPECT_GT(rows, 3000u);
  ::testing::Test::RecordProperty("worst_centroid_error_px", std::to_string(worst));
}

TEST(StripeRenderer, CentroidMatchesTruthWithoutNoiseMono8) {
  check_centroids("default", FrameFormat::Mono8, 0.05, 50.0f);
}
TEST(StripeRenderer, CentroidMatchesTruthWithoutNoiseMono16) {
  check_centroids("cube-occludes-pyramid", FrameFormat::Mono16, 0.05, 1.0f);
}

TEST(StripeRenderer, DeterministicPerSeed) {
  const auto s = load("default");
  fs::sim::StripeRenderer r(s);
  Frame a(s, FrameFormat::Mono8), b(s, FrameFormat::Mono8), c(s, FrameFormat::Mono8);
  r.render_step(200, 42, a.fb);
  r.render_step(100, 42, c.fb);  // something else in between
  r.render_step(200, 42, b.fb);
  EXPECT_EQ(a.storage, b.storage);
  r.render_step(200, 43, c.fb);
  EXPECT_NE(a.storage, c.storage);
  fs::sim::StripeRenderer other(s);  // a second renderer gives the same frame
  other.render_step(200, 42, c.fb);
  EXPECT_EQ(a.storage, c.storage);
}

TEST(StripeRenderer, BackgroundNoiseHasTheConfiguredLevel) {
  const auto s = load("cube");
  fs::sim::RenderOptions opt;
  opt.sensor_noise = 3.0;
  fs::sim::StripeRenderer r(s, opt);
  Frame f(s, FrameFormat::Mono16);
  r.render_step(0, 7, f.fb);
  double sum = 0.0, sum2 = 0.0;
  std::size_t n = 0;
  for (std::uint32_t row = 0; row < f.fb.height; row += 3)
    for (std::uint32_t x = 700; x < 1100; ++x) {  // the stripe of step 0 is at the image's left side
      const double v = f.at(row, x) / 257.0;
      sum += v;
      sum2 += v * v;
      ++n;
    }
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  EXPECT_NEAR(mean, opt.ambient, 0.1);
  EXPECT_NEAR(sd, 3.0, 0.15);
  ASSERT_TRUE(r.truth()[512].valid());
  EXPECT_LT(r.truth()[512].column, 300.0);
}

TEST(StripeRenderer, WidthAndPeakFollowDistanceAndIncidence) {
  // Peak: laser_peak * cos(incidence) * (reference distance / distance)^2.
  // Width: on the surface, the sheet (sigma = sheet_sigma + divergence * distance) leaves a band of
  // half-width a = sheet / |n_L . d| across the stripe (d: in the surface, across the stripe line l). In the
  // image, the profile's sigma along the row is the horizontal distance, on that row, to the band's edge X +
  // a d + t l, combined with the optics blur. Checked here by solving for the edge on the row independently.
  const auto s = load("default");
  fs::sim::RenderOptions opt;
  opt.noise_scale = 0.0;
  fs::sim::StripeRenderer r(s, opt);
  Frame f(s, FrameFormat::Mono8);
  const auto& cam = s.calibration.camera;
  int rows = 0, object_rows = 0;
  double widest = 0.0, narrowest = 1e9;
  for (double step = 20; step <= 260; step += 40) {
    r.render_step(step, 1, f.fb);
    const fs::Plane laser = s.calibration.laser.plane_at_step(step);
    for (std::uint32_t row = 0; row < f.fb.height; row += 3) {
      const auto& t = r.truth()[row];
      if (!t.valid()) continue;
      ++rows;
      object_rows += t.object > 0 ? 1 : 0;
      const double expected_peak =
          opt.laser_peak * t.cos_incidence * std::pow(opt.reference_distance_mm / t.laser_distance, 2);
      EXPECT_NEAR(r.peak()[row], expected_peak, 1e-3);
      const fs::Vec3 l = laser.n.cross(t.normal).normalized();
      const fs::Vec3 d = t.normal.cross(l).normalized();
      const double a = (opt.sheet_sigma_mm + opt.sheet_divergence * t.laser_distance) /
                       std::max(std::abs(laser.n.dot(d)), 0.05);
      const fs::Vec3 edge = t.point + a * d;
      // Newton on v(edge + x l) = row.
      double x = 0.0;
      fs::Vec2 p;
      for (int it = 0; it < 30; ++it) {
        fs::Vec2 p2;
        ASSERT_TRUE(cam.project(edge + x * l, p));
        ASSERT_TRUE(cam.project(edge + (x + 1e-3) * l, p2));
        const double dv = (p2.y() - p.y()) / 1e-3;
        if (std::abs(dv) < 1e-9) break;
        x -= (p.y() - row) / dv;
      }
      ASSERT_TRUE(cam.project(edge + x * l, p));
      if (std::abs(p.y() - row) > 1e-3) continue;  // stripe line nearly along the row: capped width
      const double h = std::abs(p.x() - t.column);
      const double expected =
          std::min(std::sqrt(h * h + opt.min_sigma_px * opt.min_sigma_px), opt.max_sigma_px);
      EXPECT_NEAR(r.sigma_px()[row], expected, 0.02 * expected + 1e-3) << "step " << step << " row " << row;
      widest = std::max(widest, expected);
      narrowest = std::min(narrowest, expected);
    }
  }
  EXPECT_GT(rows, 1500);
  EXPECT_GT(object_rows, 100);
  EXPECT_GT(widest, 1.5 * narrowest) << "widths vary with incidence";
  // Farther from the mirror, dimmer and wider on the table: the far end of the sweep vs the near end.
  r.render_step(0, 1, f.fb);
  const double far_peak = r.peak()[100], far_sigma = r.sigma_px()[100], far_d = r.truth()[100].laser_distance;
  r.render_step(499, 1, f.fb);
  const double near_peak = r.peak()[100], near_d = r.truth()[100].laser_distance;
  ASSERT_GT(far_d, near_d);
  EXPECT_LT(far_peak, near_peak);
  EXPECT_GT(far_sigma, 0.0);
}

TEST(StripeRenderer, SpuriousReflectionAddsAGhostNextToObjectRows) {
  const auto s = load("cube");
  fs::sim::RenderOptions opt;
  opt.noise_scale = 0.0;
  fs::sim::StripeRenderer plain(s, opt);
  opt.spurious_reflection = true;
  fs::sim::StripeRenderer ghost(s, opt);
  Frame a(s, FrameFormat::Mono8), b(s, FrameFormat::Mono8);
  plain.render_step(100, 1, a.fb);
  ghost.render_step(100, 1, b.fb);
  int ghost_rows = 0;
  for (std::uint32_t row = 0; row < a.fb.height; ++row) {
    const auto& t = plain.truth()[row];
    if (!t.valid()) continue;
    const auto gx = static_cast<std::uint32_t>(std::lround(t.column + opt.reflection_offset_px));
    if (gx >= a.fb.width) continue;
    if (t.object > 0) {
      EXPECT_GT(b.at(row, gx), a.at(row, gx) + 5) << row;
      ++ghost_rows;
    } else {
      EXPECT_EQ(b.at(row, gx), a.at(row, gx)) << row;
    }
  }
  EXPECT_GT(ghost_rows, 50);
}

TEST(StripeRenderer, RejectsMismatchedBuffers) {
  const auto s = load("cube");
  fs::sim::StripeRenderer r(s);
  Frame f(s, FrameFormat::Mono8);
  FrameBuffer bad = f.fb;
  bad.width = 640;
  EXPECT_THROW(r.render_step(0, 1, bad), fs::Error);
  bad = f.fb;
  bad.stride = 100;
  EXPECT_THROW(r.render_step(0, 1, bad), fs::Error);
  bad = f.fb;
  bad.data = nullptr;
  EXPECT_THROW(r.render_step(0, 1, bad), fs::Error);
  Frame f16(s, FrameFormat::Mono16, 2);
  bad = f16.fb;
  bad.stride += 1;  // odd stride: misaligned 16-bit rows
  EXPECT_THROW(r.render_step(0, 1, bad), fs::Error);
  bad = f16.fb;
  bad.data += 1;
  EXPECT_THROW(r.render_step(0, 1, bad), fs::Error);
  EXPECT_NO_THROW(r.render_step(0, 1, f16.fb));
}

TEST(StripeRenderer, RenderDoesNotAllocateAfterConstruction) {
  const auto s = load("default");
  fs::sim::StripeRenderer r(s);
  Frame f8(s, FrameFormat::Mono8), f16(s, FrameFormat::Mono16);
  r.render_step(10, 1, f8.fb);  // warm-up
  g_allocations = 0;
  g_counting = true;
  for (double step : {0.0, 77.0, 250.5, 499.0}) {
    r.render_step(step, 5, f8.fb);
    r.render_step(step, 5, f16.fb);
  }
  r.options().spurious_reflection = true;
  r.render_step(250, 5, f8.fb);
  r.options().speckle_grain_px = 1.5;  // the correlated pattern is rebuilt in place
  r.render_step(250, 5, f8.fb);
  g_counting = false;
  EXPECT_EQ(g_allocations.load(), 0);
}

// The correlated speckle pattern (RenderOptions::speckle_grain_px, normalized to unit variance): the
// correlation exp(-d^2 / (2 grain^2)) at distance d along the row and between rows, small grains included
// (0.5 px: 0.135 at lag 1, which a sampled Gaussian blur misses).
TEST(StripeRenderer, SpeckleGrainHasTheConfiguredCorrelation) {
  const auto s = load("cube");
  constexpr std::uint32_t T = fs::sim::StripeRenderer::kSpeckleTile;
  for (const double grain : {0.5, 1.0, 2.0, 4.0}) {
    fs::sim::RenderOptions opt;
    opt.speckle_grain_px = grain;
    const fs::sim::StripeRenderer r(s, opt);
    const auto t = r.speckle_tile();
    ASSERT_EQ(t.size(), std::size_t{T} * T);
    for (const std::uint32_t d : {1u, 2u, 3u}) {
      double along = 0.0, across = 0.0;
      for (std::uint32_t y = 0; y < T; ++y)
        for (std::uint32_t x = 0; x < T; ++x) {
          along += static_cast<double>(t[y * T + x]) * t[y * T + (x + d) % T];
          across += static_cast<double>(t[y * T + x]) * t[((y + d) % T) * T + x];
        }
      const double expected = std::exp(-0.5 * d * d / (grain * grain));
      // The tile holds ~(512 / grain)^2 grains: the sample correlation's spread is ~3 grain / 512.
      const double tol = 0.01 + 0.01 * grain;
      EXPECT_NEAR(along / t.size(), expected, tol) << "grain " << grain << ", d " << d;
      EXPECT_NEAR(across / t.size(), expected, tol) << "grain " << grain << ", d " << d;
    }
  }
}

// In a rendered frame (speckle alone: no read or shot noise, Mono16 against rounding), the relative deviation
// of the stripe's pixels from the noise-free profile is the speckle: correlated between neighbouring pixels
// and rows with a grain, not without one; and a grain of 0 renders the frames it always did.
TEST(StripeRenderer, RenderedSpeckleIsCorrelatedWithAGrain) {
  const auto s = load("cube");
  const auto deviations = [&](double grain, double step, std::vector<double>& dev, std::vector<int>& col) {
    fs::sim::RenderOptions opt;
    opt.sensor_noise = 0.0;
    opt.shot_noise = 0.0;
    opt.speckle_grain_px = grain;
    fs::sim::StripeRenderer r(s, opt);
    Frame f(s, FrameFormat::Mono16);
    r.render_step(step, 3, f.fb);
    dev.assign(std::size_t{f.fb.height} * 3, 0.0);
    col.assign(f.fb.height, -1);
    for (std::uint32_t row = 0; row < f.fb.height; ++row) {
      const auto& t = r.truth()[row];
      if (!t.valid() || r.peak()[row] < 60.0f) continue;
      const int c = static_cast<int>(std::lround(t.column));
      if (c < 1 || c + 1 >= static_cast<int>(f.fb.width)) continue;
      col[row] = c;
      for (int k = 0; k < 3; ++k) {  // the pixels c - 1, c, c + 1: near the peak, the speckle dominates
        const int x = c - 1 + k;
        const double dx = x - t.column, sg = r.sigma_px()[row];
        const double clean = r.peak()[row] * std::exp(-0.5 * dx * dx / (sg * sg));
        dev[row * 3 + static_cast<std::size_t>(k)] =
            (f.at(row, static_cast<std::uint32_t>(x)) / 257.0 - opt.ambient) / clean - 1.0;
      }
    }
  };
  const auto correlation = [](const std::vector<double>& a, const std::vector<double>& b) {
    double ab = 0.0, aa = 0.0, bb = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      ab += a[i] * b[i];
      aa += a[i] * a[i];
      bb += b[i] * b[i];
    }
    return ab / std::sqrt(aa * bb);
  };
  for (const double grain : {0.0, 2.0}) {
    std::vector<double> dev;
    std::vector<int> col;
    deviations(grain, 200.0, dev, col);
    std::vector<double> left, right, up, down;  // pixel pairs: (c, c + 1) in a row; (c, c) in rows r, r + 1
    for (std::size_t row = 0; row + 1 < col.size(); ++row) {
      if (col[row] < 0) continue;
      left.push_back(dev[row * 3 + 1]);
      right.push_back(dev[row * 3 + 2]);
      if (col[row + 1] == col[row]) {
        up.push_back(dev[row * 3 + 1]);
        down.push_back(dev[(row + 1) * 3 + 1]);
      }
    }
    ASSERT_GT(left.size(), 500u);
    ASSERT_GT(up.size(), 100u);
    const double c_row = correlation(left, right), c_rows = correlation(up, down);
    std::printf(
        "speckle grain %.1f px: correlation of neighbouring pixels %.3f, of rows %.3f (%zu, %zu pairs)\n",
        grain, c_row, c_rows, left.size(), up.size());
    if (grain == 0.0) {
      EXPECT_LT(std::abs(c_row), 0.1);
      EXPECT_LT(std::abs(c_rows), 0.15);
    } else {
      const double expected = std::exp(-0.5 / (grain * grain));  // 0.88
      EXPECT_NEAR(c_row, expected, 0.08);
      EXPECT_NEAR(c_rows, expected, 0.1);
    }
  }
  // A grain set and cleared leaves nothing behind: the same frame as a renderer that never had one.
  fs::sim::StripeRenderer plain(s), cleared(s, [] {
    fs::sim::RenderOptions o;
    o.speckle_grain_px = 2.0;
    return o;
  }());
  cleared.options().speckle_grain_px = 0.0;
  Frame a(s, FrameFormat::Mono8), b(s, FrameFormat::Mono8);
  plain.render_step(120, 9, a.fb);
  cleared.render_step(120, 9, b.fb);
  EXPECT_EQ(a.storage, b.storage);
}

}  // namespace
