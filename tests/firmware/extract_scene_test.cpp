// Stripe extraction on frames of the scene renderer (hw-sim/scene) against its per-row ground truth, for each
// sub-pixel method and several noise levels (RenderOptions::noise_scale: 1 = the renderer's default sensor
// noise, shot noise and 12 % laser speckle). Prints the error table quoted in docs/performance.md (stripe
// extraction) next to the Cramer-Rao bound of the renderer's noise model: the mean |error| an efficient
// unbiased per-row estimator would reach (sqrt(2/pi) * sqrt(CRB), averaged over the rows).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "firmware/extract/along_stripe.hpp"
#include "firmware/extract/gauss_ml.hpp"
#include "firmware/extract/stripe_extractor.hpp"
#include "hw-sim/scene/scene.hpp"
#include "hw-sim/scene/stripe_renderer.hpp"
#include "support/test_paths.hpp"

namespace fs::test {
namespace {

struct Err {
  double mean = 0.0;
  double bound = 0.0;  // mean over the measured rows of sqrt(2/pi) * sqrt(CRB)
  int rows = 0, outliers = 0, rejected = 0;
};

Err measure(const sim::Scene& scene, double noise_scale, fw::SubpixelMethod method,
            const fw::ExtractParams& base = fw::ExtractParams{}) {
  sim::RenderOptions o;
  o.noise_scale = noise_scale;
  sim::StripeRenderer r(scene, o);
  const auto& cam = scene.calibration.camera;
  std::vector<std::uint8_t> img(static_cast<std::size_t>(cam.width) * cam.height);
  fw::ExtractParams p = base;
  p.method = method;
  Err e;
  double sum = 0.0, bound = 0.0;
  const fw::detail::SensorNoise noise{o.sensor_noise * noise_scale, o.shot_noise * noise_scale,
                                      o.speckle * noise_scale};
  for (double step : {80.0, 200.0, 260.0, 330.0}) {
    r.render_step(step, 7 + static_cast<std::uint64_t>(step),
                  sim::FrameBuffer{img.data(), cam.width, cam.height, cam.width, sim::FrameFormat::Mono8});
    for (std::uint32_t v = 0; v < cam.height; ++v) {
      const auto& t = r.truth()[v];
      if (!t.valid()) continue;
      const fw::RowPeak rp = fw::extract_row<std::uint8_t>(
          img.data() + static_cast<std::size_t>(v) * cam.width, cam.width, 1, 255.0, p);
      if (rp.status != fw::RowStatus::Ok) {
        ++e.rejected;
        continue;
      }
      const double d = std::abs(rp.col - t.column);
      if (d > 1.0) {
        ++e.outliers;
        continue;
      }
      sum += d;
      bound +=
          std::sqrt(2.0 / M_PI *
                    fw::detail::centre_crb(t.column, r.sigma_px()[v], r.peak()[v], o.ambient, 255.0, noise));
      ++e.rows;
    }
  }
  e.mean = e.rows ? sum / e.rows : 1e9;
  e.bound = e.rows ? bound / e.rows : 0.0;
  return e;
}

TEST(ExtractScene, ErrorVersusNoiseOnCubeFrames) {
  const sim::Scene scene = sim::load_scene(source_dir() / "hw-sim/scenes/cube.json");
  std::printf("noise_scale  method       mean|err|px  CRB mean|err|  rows  outliers(>1px)  rejected\n");
  for (double ns : {0.0, 0.25, 0.5, 1.0}) {
    for (auto m :
         {fw::SubpixelMethod::CentreOfGravity, fw::SubpixelMethod::Gaussian3, fw::SubpixelMethod::BlaisRioux,
          fw::SubpixelMethod::GaussFit, fw::SubpixelMethod::GaussMl, fw::SubpixelMethod::GaussLog}) {
      const Err e = measure(scene, ns, m);
      std::printf("%11.2f  %-11s  %11.4f  %13.4f  %4d  %14d  %8d\n", ns, fw::to_string(m), e.mean, e.bound,
                  e.rows, e.outliers, e.rejected);
      if (m == fw::ExtractParams{}.method) {
        EXPECT_EQ(e.outliers, 0) << "noise " << ns;
        EXPECT_EQ(e.rejected, 0) << "noise " << ns;
        // 1.0: the bound itself is ~0.058 px, above the 0.05 px target (docs/performance.md):
        // speckle-limited.
        const double limit = ns == 0.0 ? 0.01 : ns <= 0.25 ? 0.02 : ns <= 0.5 ? 0.035 : 0.065;
        EXPECT_LE(e.mean, limit) << "noise " << ns;
        // Efficiency: within 10 % of the Cramer-Rao bound wherever noise dominates quantization.
        if (ns >= 0.25) {
          EXPECT_LE(e.mean, 1.10 * e.bound) << "noise " << ns;
        }
      }
    }
  }
}

TEST(ExtractScene, GaussMlToleratesAWrongNoiseModel) {
  // The ML weights come from ExtractParams' sensor model (default = the renderer's). A model off by 2x in
  // speckle or read noise, or without shot noise, must cost little at the default noise.
  const sim::Scene scene = sim::load_scene(source_dir() / "hw-sim/scenes/cube.json");
  struct Case {
    const char* name;
    double read, shot, speckle;
  };
  std::printf("gauss-ml at noise_scale 1 with the model:        mean|err|px\n");
  for (const Case& c : {Case{"default (1.5, 0.35, 0.12)", 1.5, 0.35, 0.12},
                        Case{"speckle / 2", 1.5, 0.35, 0.06}, Case{"speckle x 2", 1.5, 0.35, 0.24},
                        Case{"read x 2", 3.0, 0.35, 0.12}, Case{"no shot noise", 1.5, 0.0, 0.12}}) {
    fw::ExtractParams p;
    p.read_noise = c.read;
    p.shot_noise = c.shot;
    p.speckle = c.speckle;
    const Err e = measure(scene, 1.0, fw::SubpixelMethod::GaussMl, p);
    std::printf("  %-28s                %.4f\n", c.name, e.mean);
    EXPECT_EQ(e.outliers, 0) << c.name;
    EXPECT_LE(e.mean, 0.07) << c.name;  // vs 0.113 of the intensity-weighted fit
  }
}

// extract_frame works through blocks of rows (the batched GaussMl fit, rows in SIMD lanes); extract_row fits
// a row alone. Both must give the same points bit for bit, for every method and pixel format, on the
// renderer's frames (so the accuracy measured above through extract_row is the frame path's).
TEST(ExtractScene, FrameGivesTheRowByRowResults) {
  const sim::Scene scene = sim::load_scene(source_dir() / "hw-sim/scenes/cube.json");
  sim::StripeRenderer r(scene);
  const auto& cam = scene.calibration.camera;
  const std::uint32_t w = cam.width, h = cam.height;
  std::vector<std::uint8_t> img(static_cast<std::size_t>(w) * h), yuyv(img.size() * 2);
  std::vector<std::uint16_t> img16(img.size());
  std::vector<msg::StripePoint> out(h);
  int compared = 0;
  for (double step : {30.0, 250.0, 470.0}) {
    r.render_step(step, 3, sim::FrameBuffer{img.data(), w, h, w, sim::FrameFormat::Mono8});
    for (std::size_t i = 0; i < img.size(); ++i) {
      img16[i] = static_cast<std::uint16_t>(img[i] * 257 + (i % 7));
      yuyv[2 * i] = img[i];
      yuyv[2 * i + 1] = static_cast<std::uint8_t>(i);
    }
    for (auto m : {fw::SubpixelMethod::GaussMl, fw::SubpixelMethod::GaussLog,
                   fw::SubpixelMethod::CentreOfGravity, fw::SubpixelMethod::GaussFit}) {
      fw::ExtractParams p;
      p.method = m;
      p.along_stripe = 0;  // the per-row centres (the refinement across rows: the next test)
      for (int format = 0; format < 3; ++format) {
        const fw::FrameView f =
            format == 0   ? fw::FrameView{img.data(), w, h, w, fw::PixelFormat::Mono8, 0, 0, 0}
            : format == 1 ? fw::FrameView{reinterpret_cast<const std::uint8_t*>(img16.data()),
                                          w,
                                          h,
                                          2 * w,
                                          fw::PixelFormat::Mono16,
                                          0,
                                          0,
                                          0}
                          : fw::FrameView{yuyv.data(), w, h, 2 * w, fw::PixelFormat::Yuyv, 0, 0, 0};
        const fw::ExtractCounts c = fw::extract_frame(f, p, out);
        std::uint32_t k = 0, no_stripe = 0;
        for (std::uint32_t v = 0; v < h; ++v) {
          const fw::RowPeak rp =
              format == 0 ? fw::extract_row<std::uint8_t>(img.data() + std::size_t{v} * w, w, 1, 255.0, p)
              : format == 1
                  ? fw::extract_row<std::uint16_t>(img16.data() + std::size_t{v} * w, w, 1, 65535.0, p)
                  : fw::extract_row<std::uint8_t>(yuyv.data() + std::size_t{v} * 2 * w, w, 2, 255.0, p);
          no_stripe += rp.status == fw::RowStatus::NoStripe;
          if (rp.status != fw::RowStatus::Ok) continue;
          ASSERT_LT(k, c.points) << "row " << v;
          const msg::StripePoint& pt = out[k++];
          ASSERT_EQ(pt.row, v);
          ASSERT_EQ(pt.col, static_cast<float>(rp.col)) << "row " << v << " format " << format;
          ASSERT_EQ(pt.width, static_cast<float>(rp.width)) << "row " << v;
          ASSERT_EQ(pt.peak, static_cast<std::uint16_t>(std::min(rp.peak, 65535.0))) << "row " << v;
          ++compared;
        }
        EXPECT_EQ(k, c.points);
        EXPECT_EQ(no_stripe, c.no_stripe);
        EXPECT_EQ(c.rows, h);
      }
    }
  }
  EXPECT_GT(compared, 3 * 3 * 3 * 500);
}

// With the along-stripe refinement (the default), extract_frame = the row-by-row results refined by
// refine_along_stripe with the frame's along_stripe_scale, bit for bit.
TEST(ExtractScene, FrameIsTheRowsRefinedAlongTheStripe) {
  const sim::Scene scene = sim::load_scene(source_dir() / "hw-sim/scenes/cube.json");
  sim::StripeRenderer r(scene);
  const auto& cam = scene.calibration.camera;
  const std::uint32_t w = cam.width, h = cam.height;
  std::vector<std::uint8_t> img(static_cast<std::size_t>(w) * h);
  std::vector<msg::StripePoint> out(h), rows;
  const fw::ExtractParams p;
  ASSERT_EQ(p.along_stripe, 15u);
  for (double step : {30.0, 250.0, 470.0}) {
    r.render_step(step, 3, sim::FrameBuffer{img.data(), w, h, w, sim::FrameFormat::Mono8});
    const fw::ExtractCounts c =
        fw::extract_frame(fw::FrameView{img.data(), w, h, w, fw::PixelFormat::Mono8, 0, 0, 0}, p, out);
    rows.clear();
    for (std::uint32_t v = 0; v < h; ++v) {
      const fw::RowPeak rp = fw::extract_row<std::uint8_t>(img.data() + std::size_t{v} * w, w, 1, 255.0, p);
      if (rp.status != fw::RowStatus::Ok) continue;
      rows.push_back(msg::StripePoint{static_cast<std::uint16_t>(v), static_cast<float>(rp.col),
                                      static_cast<std::uint16_t>(rp.peak), static_cast<float>(rp.width)});
    }
    ASSERT_EQ(rows.size(), c.points);
    const double sigma = fw::along_stripe_scale(rows, p.along_stripe);
    EXPECT_GT(sigma, 0.03);  // the per-row noise of the default renderer noise (~0.075 px)
    EXPECT_LT(sigma, 0.15);
    fw::refine_along_stripe(rows, p.along_stripe, sigma);
    int moved = 0;
    for (std::size_t k = 0; k < rows.size(); ++k) {
      ASSERT_EQ(out[k].row, rows[k].row);
      ASSERT_EQ(out[k].col, rows[k].col) << "row " << rows[k].row;
      moved +=
          out[k].col !=
          static_cast<float>(
              fw::extract_row<std::uint8_t>(img.data() + std::size_t{rows[k].row} * w, w, 1, 255.0, p).col);
    }
    EXPECT_GT(moved, static_cast<int>(rows.size()) * 9 / 10);  // nearly every row is refined
  }
}

}  // namespace
}  // namespace fs::test
