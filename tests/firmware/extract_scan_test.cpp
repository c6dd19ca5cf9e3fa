// The building blocks of stripe extraction (firmware/extract/): the row pass (SIMD path == portable path,
// bit for bit, on rows of every length and content), the max outside a window, fast_ln against std::log, and
// the Cramer-Rao bound helper.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <memory>
#include <random>
#include <vector>

#include "firmware/extract/fast_log.hpp"
#include "firmware/extract/gauss_ml.hpp"
#include "firmware/extract/row_scan.hpp"

namespace fs::fw::detail {
namespace {

template <typename T>
void expect_same_scan(const RowScan<T>& a, const RowScan<T>& b) {
  ASSERT_EQ(a.n, b.n);
  ASSERT_EQ(a.nblocks, b.nblocks);
  EXPECT_EQ(a.sum, b.sum);
  EXPECT_EQ(a.max, b.max);
  for (std::uint32_t k = 0; k < a.nblocks; ++k)
    ASSERT_EQ(0, std::memcmp(a.lane_max[k], b.lane_max[k], sizeof(a.lane_max[k]))) << "block " << k;
}

TEST(ExtractScan, SimdPassEqualsPortablePass) {
  std::printf("8-bit row pass: %s\n", scan_row_u8_isa());
  std::mt19937 rng(42);
  std::vector<std::uint8_t> row(kMaxBlocks * kBlock + 100);
  for (std::uint32_t n : {1u, 5u, 63u, 64u, 65u, 127u, 640u, 1280u, 1283u, 4096u, kMaxBlocks * kBlock,
                          kMaxBlocks * kBlock + 100}) {
    for (int fill = 0; fill < 3; ++fill) {
      for (auto& v : row) v = static_cast<std::uint8_t>(fill == 0 ? rng() : fill == 1 ? 255 : rng() % 3);
      auto a = std::make_unique<RowScan<std::uint8_t>>();
      auto b = std::make_unique<RowScan<std::uint8_t>>();
      scan_row<std::uint8_t, 1>(row.data(), n, *a);
      scan_row_portable<std::uint8_t, 1>(row.data(), n, *b);
      expect_same_scan(*a, *b);
      // Against a plain loop.
      const std::uint32_t m = std::min(n, kMaxBlocks * kBlock);
      std::uint64_t sum = 0;
      std::uint8_t mx = 0;
      for (std::uint32_t i = 0; i < m; ++i) {
        sum += row[i];
        mx = std::max(mx, row[i]);
      }
      EXPECT_EQ(a->sum, sum) << n;
      EXPECT_EQ(a->max, mx) << n;
      for (std::uint32_t k = 0; k < a->nblocks; ++k) {
        std::uint8_t bm = 0;
        for (std::uint32_t i = k * kBlock; i < std::min(m, (k + 1) * kBlock); ++i) bm = std::max(bm, row[i]);
        ASSERT_EQ(a->block_max(k), bm) << "n " << n << " block " << k;
      }
    }
  }
}

TEST(ExtractScan, SixteenBitAndStridedPasses) {
  std::mt19937 rng(7);
  std::vector<std::uint16_t> row16(3000);
  for (auto& v : row16) v = static_cast<std::uint16_t>(rng());
  auto s = std::make_unique<RowScan<std::uint16_t>>();
  scan_row<std::uint16_t, 1>(row16.data(), 3000, *s);
  std::uint64_t sum = 0;
  for (auto v : row16) sum += v;
  EXPECT_EQ(s->sum, sum);
  EXPECT_EQ(s->max, *std::max_element(row16.begin(), row16.end()));
  std::vector<std::uint8_t> yuyv(2 * 700);
  for (auto& v : yuyv) v = static_cast<std::uint8_t>(rng());
  auto y = std::make_unique<RowScan<std::uint8_t>>();
  scan_row<std::uint8_t, 2>(yuyv.data(), 700, *y);
  std::uint64_t ysum = 0;
  std::uint8_t ymax = 0;
  for (std::size_t i = 0; i < 700; ++i) {
    ysum += yuyv[2 * i];
    ymax = std::max(ymax, yuyv[2 * i]);
  }
  EXPECT_EQ(y->sum, ysum);
  EXPECT_EQ(y->max, ymax);
}

TEST(ExtractScan, MaxOutsideMatchesBruteForce) {
  std::mt19937 rng(9);
  std::vector<std::uint8_t> row(1000);
  auto s = std::make_unique<RowScan<std::uint8_t>>();
  for (int t = 0; t < 3000; ++t) {
    for (auto& v : row) v = static_cast<std::uint8_t>(rng() % 200);
    row[rng() % 1000] = 250;  // a spike somewhere
    scan_row<std::uint8_t, 1>(row.data(), 1000, *s);
    const std::int64_t lo = static_cast<std::int64_t>(rng() % 995) - 5,
                       hi = lo + static_cast<std::int64_t>(rng() % 120);
    std::uint8_t want = 0;
    for (std::int64_t i = 0; i < 1000; ++i)
      if (i < lo || i > hi) want = std::max(want, row[static_cast<std::size_t>(i)]);
    ASSERT_EQ((max_outside<std::uint8_t, 1>(row.data(), *s, lo, hi)), want) << lo << ".." << hi;
    // The 8-bit version (AVX2 on x86-64: writes over the lane maxima of the blocks [lo, hi] overlaps), also
    // on rows that end inside the last block and windows at the row ends.
    const std::uint32_t n = t % 3 ? 1000 : 1000 - static_cast<std::uint32_t>(rng() % 64);
    scan_row<std::uint8_t, 1>(row.data(), n, *s);
    // windows that hold a sample of the row (as the double-peak test's always do: the peak)
    const std::int64_t lo8 = t % 5 == 0   ? -3
                             : t % 5 == 1 ? static_cast<std::int64_t>(n) - 40
                                          : std::min<std::int64_t>(lo, n - 1);
    const std::int64_t hi8 =
        lo8 + 3 + static_cast<std::int64_t>(rng() % 60);  // windows hold a sample (the peak)
    std::uint8_t want8 = 0;
    for (std::int64_t i = 0; i < n; ++i)
      if (i < lo8 || i > hi8) want8 = std::max(want8, row[static_cast<std::size_t>(i)]);
    ASSERT_EQ(max_outside_u8(row.data(), *s, lo8, hi8), want8) << n << ": " << lo8 << ".." << hi8;
  }
}

TEST(ExtractScan, FastLogMatchesStdLog) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> e(-30.0, 30.0);
  double worst = 0.0;
  for (int i = 0; i < 200000; ++i) {
    const double x = std::exp(e(rng));
    worst = std::max(worst, std::abs(fast_ln(x) - std::log(x)));
  }
  for (double x : {1.0, 2.0, 0.5, 1.4142135623730951, 1.4142135623730954, 255.0, 1e-300, 1e300})
    worst = std::max(worst, std::abs(fast_ln(x) - std::log(x)));
  EXPECT_LT(worst, 1e-9);
}

TEST(ExtractScan, FastFloatLogAndExpMatchLibm) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> e(-80.0f, 80.0f);
  double worst_ln = 0.0, worst_exp = 0.0;
  for (int i = 0; i < 200000; ++i) {
    const float z = e(rng);
    const double x = std::exp(static_cast<double>(z));
    const float xf = static_cast<float>(x);
    worst_ln =
        std::max(worst_ln, std::abs(static_cast<double>(fast_lnf(xf)) - std::log(static_cast<double>(xf))));
    worst_exp = std::max(worst_exp, std::abs(static_cast<double>(fast_expf(z)) / x - 1.0));
  }
  EXPECT_LT(worst_ln, 2e-7 * 60);  // absolute; |ln x| up to 80: a few ulp of the result
  EXPECT_LT(worst_exp, 3e-7);
  EXPECT_GT(fast_expf(-80.0f), 0.0f);
}

TEST(ExtractScan, VectorLogAndExpEqualScalarBitForBit) {
  std::mt19937 rng(6);
  std::uniform_real_distribution<float> e(-80.0f, 80.0f);
  for (int i = 0; i < 20000; ++i) {
    f32x8 z, x;
    for (int j = 0; j < 8; ++j) {
      z[j] = e(rng);
      x[j] = std::exp(z[j]);
    }
    const f32x8 lx = fast_lnf(x), ez = fast_expf(z);
    f32x4 x4, z4;
    for (int j = 0; j < 4; ++j) {
      x4[j] = x[j + 4];
      z4[j] = z[j + 4];
    }
    const f32x4 lx4 = fast_lnf(x4), ez4 = fast_expf(z4);
    for (int j = 0; j < 8; ++j) {
      ASSERT_EQ(std::bit_cast<std::uint32_t>(lx[j]), std::bit_cast<std::uint32_t>(fast_lnf(x[j]))) << x[j];
      ASSERT_EQ(std::bit_cast<std::uint32_t>(ez[j]), std::bit_cast<std::uint32_t>(fast_expf(z[j]))) << z[j];
    }
    for (int j = 0; j < 4; ++j) {
      ASSERT_EQ(std::bit_cast<std::uint32_t>(lx4[j]), std::bit_cast<std::uint32_t>(lx[j + 4]));
      ASSERT_EQ(std::bit_cast<std::uint32_t>(ez4[j]), std::bit_cast<std::uint32_t>(ez[j + 4]));
    }
  }
}

TEST(ExtractScan, CramerRaoBoundBehaves) {
  const SensorNoise noise;
  // More signal and narrower stripes give a tighter bound; speckle sets a floor that signal cannot beat.
  const double a = centre_crb(100.3, 2.4, 160.0, 14.0, 255.0, noise);
  EXPECT_GT(a, 0.0);
  EXPECT_LT(centre_crb(100.3, 1.2, 160.0, 14.0, 255.0, noise), a);
  EXPECT_GT(centre_crb(100.3, 4.8, 160.0, 14.0, 255.0, noise), a);
  const SensorNoise half{0.75, 0.175, 0.06};
  EXPECT_NEAR(centre_crb(100.3, 2.4, 160.0, 14.0, 255.0, half), a / 4.0, a * 0.02);  // variance ~ noise^2
  // Additive noise only: the bound falls with the amplitude squared, exactly.
  const SensorNoise read_only{2.0, 0.0, 0.0};
  const double r1 = centre_crb(50.3, 2.0, 100.0, 0.0, 1e9, read_only);
  EXPECT_NEAR(centre_crb(50.3, 2.0, 200.0, 0.0, 1e9, read_only), r1 / 4.0, r1 * 1e-9);
  // Speckle only (plus the 1/12 DN^2 of quantization): doubling the signal barely helps (only the far tails
  // gain), unlike the additive case.
  const SensorNoise speckle_only{0.0, 0.0, 0.12};
  const double s1 = centre_crb(50.3, 2.0, 1e4, 0.0, 1e9, speckle_only);
  const double s2 = centre_crb(50.3, 2.0, 2e4, 0.0, 1e9, speckle_only);
  EXPECT_LT(s2, s1);
  EXPECT_GT(s2, 0.8 * s1);
}

TEST(ExtractScan, GaussMlRecoversExactGaussian) {
  for (double u : {0.0, 0.27, -0.41, 0.5}) {
    for (double s : {0.8, 1.5, 3.0, 6.0}) {
      std::vector<float> y(61 + kChunk, 0.0f);
      for (int k = 0; k < 61; ++k)
        y[k] = static_cast<float>(150.0 * std::exp(-(k - 30 - u) * (k - 30 - u) / (2 * s * s)));
      const int ic = 30 + static_cast<int>(std::lround(u));
      double c = 0.0;
      ASSERT_TRUE(gauss_ml_centre(y.data(), 61, ic, 150.0, 1e9, SensorNoise{}, c)) << u << " " << s;
      EXPECT_NEAR(c, 30.0 + u, 2e-4) << u << " " << s;  // float samples and sums
    }
  }
  // No Gaussian: a flat run, or a valley.
  std::vector<float> flat(21 + kChunk, 50.0f), valley(21 + kChunk, 0.0f);
  for (int k = 0; k < 21; ++k) valley[k] = static_cast<float>(10 + (k - 10) * (k - 10));
  double c = 0.0;
  EXPECT_FALSE(gauss_ml_centre(flat.data(), 21, 10, 50.0, 1e9, SensorNoise{}, c));
  EXPECT_FALSE(gauss_ml_centre(valley.data(), 21, 10, 110.0, 1e9, SensorNoise{}, c));
}

// A noisy Gaussian profile of kBatchHalf * 2 samples centred near sample kBatchHalf (+ u), as the extractor
// stores it: samples minus background, clipped at `clip`.
std::vector<float> noisy_profile(double u, double s, double A, double clip, std::mt19937& rng) {
  std::normal_distribution<double> n01(0.0, 1.0);
  std::vector<float> y(2 * kBatchHalf + kChunk, 0.0f);
  for (int k = 0; k < 2 * kBatchHalf; ++k) {
    const double x = k - kBatchHalf - u, S = A * std::exp(-x * x / (2 * s * s));
    y[k] = static_cast<float>(std::min(clip, S * (1.0 + 0.12 * n01(rng)) + 1.5 * n01(rng)));
  }
  return y;
}

// Both fits: GaussMl (intensity_step) and GaussLog (its first step alone).
class GaussMlBatchFit : public ::testing::TestWithParam<bool> {};

TEST_P(GaussMlBatchFit, MatchesTheOneRowFit) {
  const bool intensity_step = GetParam();
  std::printf("batched %s fit: %s\n", intensity_step ? "gauss-ml" : "gauss-log", gauss_ml_batch_isa());
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> uu(-0.5, 0.5), ss(0.6, 4.0), aa(30.0, 240.0);
  std::uniform_int_distribution<int> half(3, kBatchHalf - 1);
  int compared = 0, fitted = 0;
  double worst = 0.0;
  for (int round = 0; round < 400; ++round) {
    GaussMlBatch batch;
    batch.intensity_step = intensity_step;
    std::vector<float> win[kBatch];
    int first[kBatch], last[kBatch], ic[kBatch];
    double contrast[kBatch], clip[kBatch];
    for (int j = 0; j < kBatch; ++j) {
      clip[j] = round % 4 == 0 ? 150.0 : 1e9;  // some lanes with clipped tops
      win[j] = noisy_profile(uu(rng), ss(rng), aa(rng), clip[j], rng);
      ic[j] = static_cast<int>(std::max_element(win[j].begin(), win[j].begin() + 2 * kBatchHalf) -
                               win[j].begin());
      ic[j] = std::clamp(ic[j], 1, 2 * kBatchHalf - 2);
      first[j] = std::max(1, ic[j] - half(rng));  // windows of different widths, some cut at one side
      last[j] = std::min(2 * kBatchHalf - 1, ic[j] + half(rng));
      contrast[j] = win[j][ic[j]];
      for (int x = -kBatchHalf; x < kBatchHalf; ++x) {
        const int k = ic[j] + x;  // outside the lane's window: other data (must not matter)
        batch.y[kBatchHalf + x][j] = k >= first[j] && k <= last[j] ? win[j][k] : 77.0f;
      }
      batch.xa[j] = first[j] - ic[j];
      batch.xb[j] = last[j] - ic[j];
      batch.contrast[j] = contrast[j];
      batch.clip[j] = clip[j];
    }
    GaussMlBatch portable = batch, avx2 = batch, alone = batch;
    gauss_ml_centre_batch(batch, SensorNoise{});
    gauss_ml_centre_batch_portable(portable, SensorNoise{});
    ASSERT_EQ(0, std::memcmp(batch.centre, portable.centre, sizeof batch.centre));
    ASSERT_EQ(0, std::memcmp(batch.ok, portable.ok, sizeof batch.ok));
    if (gauss_ml_centre_batch_avx2(avx2, SensorNoise{})) {  // also where the dispatch picks AVX-512VL
      ASSERT_EQ(0, std::memcmp(batch.centre, avx2.centre, sizeof batch.centre));
      ASSERT_EQ(0, std::memcmp(batch.ok, avx2.ok, sizeof batch.ok));
    }
    // Lane 0 fitted alone (the other lanes emptied) gives the same bits: results depend on their lane only.
    for (int j = 1; j < kBatch; ++j) {
      alone.xa[j] = alone.xb[j] = 0;
      for (int x = 0; x < 2 * kBatchHalf; ++x) alone.y[x][j] = 0.0f;
    }
    gauss_ml_centre_batch(alone, SensorNoise{});
    ASSERT_EQ(std::bit_cast<std::uint64_t>(alone.centre[0]) * alone.ok[0],
              std::bit_cast<std::uint64_t>(batch.centre[0]) * batch.ok[0]);
    ASSERT_EQ(alone.ok[0], batch.ok[0]);
    for (int j = 0; j < kBatch; ++j) {
      std::vector<float> y(win[j].begin() + first[j], win[j].begin() + last[j] + 1);
      y.resize(y.size() + kChunk, 0.0f);
      double c = 0.0;
      const bool ok = gauss_ml_centre(y.data(), last[j] - first[j] + 1, ic[j] - first[j], contrast[j],
                                      clip[j], SensorNoise{}, c, intensity_step);
      ++compared;
      ASSERT_EQ(ok, batch.ok[j] != 0) << "round " << round << " lane " << j;
      if (!ok) continue;
      ++fitted;
      const double diff = std::abs(first[j] + c - (ic[j] + batch.centre[j]));
      worst = std::max(worst, diff);
      // Float sums added in another order: ~1e-6 px typically, up to ~1e-4 on ill-conditioned windows; a
      // different sample set or fallback would show as 1e-3 or more.
      EXPECT_LT(diff, 2e-4) << "round " << round << " lane " << j;
    }
  }
  std::printf("%d of %d lanes fitted, largest difference to the one-row fit %.2g px\n", fitted, compared,
              worst);
  EXPECT_GT(fitted, compared * 9 / 10);
}
INSTANTIATE_TEST_SUITE_P(ExtractScan, GaussMlBatchFit, ::testing::Values(true, false),
                         [](const auto& info) { return info.param ? "GaussMl" : "GaussLog"; });

}  // namespace
}  // namespace fs::fw::detail
