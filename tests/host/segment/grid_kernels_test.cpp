// The vectorized per-row kernels of the normal pass (host/segment/grid_kernels.hpp) on small hand-made grids.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "host/segment/grid_kernels.hpp"

namespace {

using namespace fs::host::seg::kernels;

constexpr float kNan = std::numeric_limits<float>::quiet_NaN();

// A w x h grid of the plane z = a x + b y + c sampled at x = col, y = row (SoA), viewpoint high above.
struct Grid {
  int w, h;
  std::vector<float> X, Y, Z, J2;
  Grid(int w_, int h_, float a, float b, float c, float jump) : w(w_), h(h_) {
    for (int r = 0; r < h; ++r)
      for (int k = 0; k < w; ++k) {
        X.push_back(float(k));
        Y.push_back(float(r));
        Z.push_back(a * float(k) + b * float(r) + c);
        J2.push_back(jump * jump);
      }
  }
  std::size_t at(int r, int k) const { return std::size_t(r) * std::size_t(w) + std::size_t(k); }
};

TEST(GridKernels, SoaRowMarksNonFiniteAndHugeCoordinatesAsNoData) {
  const float inf = std::numeric_limits<float>::infinity();
  const std::vector<float> S = {1, 2, 3, kNan, 0, 0, 0, inf, 0, 0, 0, 2e7f, 4, 5, 6};
  std::vector<float> X(5), Y(5), Z(5), J2(5), DI(5);
  std::vector<std::uint8_t> valid(5);
  soa_row(S.data(), 5, {0, 0, 100}, 2.0f, 0.0f, 0.5f, 1e-4f, X.data(), Y.data(), Z.data(), J2.data(),
          DI.data(), valid.data());
  EXPECT_EQ(valid, (std::vector<std::uint8_t>{1, 0, 0, 0, 1}));
  EXPECT_FLOAT_EQ(X[0], 1.f);
  EXPECT_FLOAT_EQ(Z[4], 6.f);
  EXPECT_TRUE(std::isnan(X[1]) && std::isnan(Y[2]) && std::isnan(Z[3]));
  EXPECT_FLOAT_EQ(J2[0], 4.f);
  EXPECT_FLOAT_EQ(J2[1], 0.f);
  // dist = dist_abs + dist_rel * range^2, range^2 = 1 + 4 + 97^2
  EXPECT_NEAR(DI[0], 0.5f + 1e-4f * (1.f + 4.f + 97.f * 97.f), 1e-5f);
  EXPECT_FLOAT_EQ(DI[3], 0.f);
}

TEST(GridKernels, NormalsOfATiltedPlaneTowardTheViewpointWithAreaAndTangentLengths) {
  Grid g(12, 7, 0.5f, -0.25f, 10.f, 3.f);
  const int r = 3;
  std::vector<float> NX(g.X.size()), NY(g.X.size()), NZ(g.X.size()), AR(g.X.size()), LU(g.X.size()),
      LV(g.X.size());
  const std::size_t b = g.at(r, 0), W = std::size_t(g.w);
  normals_row_fast(g.X.data() + b, g.Y.data() + b, g.Z.data() + b, g.J2.data() + b, 0.f, 0.f, 2, g.w - 2, 2,
                   2, W, {5, 3, 500}, NX.data() + b, NY.data() + b, NZ.data() + b, AR.data() + b,
                   LU.data() + b, LV.data() + b);
  const float len = std::sqrt(0.25f + 0.0625f + 1.f);
  for (int k = 2; k < g.w - 2; ++k) {
    const std::size_t i = b + std::size_t(k);
    EXPECT_NEAR(NX[i], -0.5f / len, 1e-5f) << k;
    EXPECT_NEAR(NY[i], 0.25f / len, 1e-5f) << k;
    EXPECT_NEAR(NZ[i], 1.f / len, 1e-5f) << k;  // +z: toward the viewpoint above
    EXPECT_NEAR(AR[i], len, 1e-5f);             // |(1,0,a) x (0,1,b)| per unit cell
    EXPECT_NEAR(LU[i], 1.25f, 1e-5f);
    EXPECT_NEAR(LV[i], 1.0625f, 1e-5f);
  }
  // seen from below, the same plane's normals point down
  normals_row_fast(g.X.data() + b, g.Y.data() + b, g.Z.data() + b, g.J2.data() + b, 0.f, 0.f, 2, g.w - 2, 2,
                   2, W, {5, 3, -500}, NX.data() + b, NY.data() + b, NZ.data() + b, AR.data() + b,
                   LU.data() + b, LV.data() + b);
  EXPECT_NEAR(NZ[b + 5], -1.f / len, 1e-5f);
  // spans of 1 cell along the row and 2 across it: the same normals, area and lengths per cell
  normals_row_fast(g.X.data() + b, g.Y.data() + b, g.Z.data() + b, g.J2.data() + b, 0.f, 0.f, 1, g.w - 1, 1,
                   2, W, {5, 3, 500}, NX.data() + b, NY.data() + b, NZ.data() + b, AR.data() + b,
                   LU.data() + b, LV.data() + b);
  for (int k = 1; k < g.w - 1; ++k) {
    const std::size_t i = b + std::size_t(k);
    EXPECT_NEAR(NX[i], -0.5f / len, 1e-5f) << k;
    EXPECT_NEAR(NZ[i], 1.f / len, 1e-5f) << k;
    EXPECT_NEAR(AR[i], len, 1e-5f);
    EXPECT_NEAR(LU[i], 1.25f, 1e-5f);
    EXPECT_NEAR(LV[i], 1.0625f, 1e-5f);
  }
}

TEST(GridKernels, FastPathRefusesMissingNeighboursAndDepthJumps) {
  Grid g(12, 7, 0.f, 0.f, 0.f, 1.f);
  const int r = 3;
  const std::size_t b = g.at(r, 0), W = std::size_t(g.w);
  g.X[g.at(r, 7)] = kNan;     // cell 5 (left of 7 at +-2) and 9 see a missing neighbour
  g.Z[g.at(r - 2, 3)] = 5.f;  // cell 3: its upper neighbour at span 2 is beyond the jump threshold
  std::vector<float> NX(g.X.size()), NY(g.X.size()), NZ(g.X.size()), AR(g.X.size()), LU(g.X.size()),
      LV(g.X.size());
  normals_row_fast(g.X.data() + b, g.Y.data() + b, g.Z.data() + b, g.J2.data() + b, 0.f, 0.f, 2, g.w - 2, 2,
                   2, W, {5, 3, 100}, NX.data() + b, NY.data() + b, NZ.data() + b, AR.data() + b,
                   LU.data() + b, LV.data() + b);
  for (int k : {3, 5, 7, 9}) {
    EXPECT_TRUE(std::isnan(NX[b + std::size_t(k)])) << k;
    EXPECT_EQ(AR[b + std::size_t(k)], 0.f) << k;
  }
  for (int k : {2, 4, 6, 8}) EXPECT_NEAR(NZ[b + std::size_t(k)], 1.f, 1e-6f) << k;
  // a floor of the threshold across the rows (6 mm per cell: a coarse sweep) takes cell 3's step; one along
  // the rows does not
  normals_row_fast(g.X.data() + b, g.Y.data() + b, g.Z.data() + b, g.J2.data() + b, 36.f, 0.f, 2, g.w - 2, 2,
                   2, W, {5, 3, 100}, NX.data() + b, NY.data() + b, NZ.data() + b, AR.data() + b,
                   LU.data() + b, LV.data() + b);
  EXPECT_TRUE(std::isnan(NX[b + 3]));
  normals_row_fast(g.X.data() + b, g.Y.data() + b, g.Z.data() + b, g.J2.data() + b, 0.f, 36.f, 2, g.w - 2, 2,
                   2, W, {5, 3, 100}, NX.data() + b, NY.data() + b, NZ.data() + b, AR.data() + b,
                   LU.data() + b, LV.data() + b);
  EXPECT_FALSE(std::isnan(NX[b + 3]));
  EXPECT_TRUE(std::isnan(NX[b + 5]));  // a missing neighbour stays missing
}

TEST(GridKernels, ContinuityKeepsGrazingStepsAndSeparatesJumpsAlongTheRay) {
  // viewpoint at the origin looking along +x; cell 0 at x = 100
  std::vector<float> X = {100, 100, 110, kNan}, Y = {0, 8, 0, 0}, Z = {0, 0, 0, 0}, J2 = {1, 1, 1, 1};
  const Viewpoint vp{0, 0, 0};
  const float jmax2 = 25.f * 25.f, cos2 = std::pow(std::cos(6.f * 3.14159265f / 180.f), 2.f);
  EXPECT_TRUE(continuous(X.data(), Y.data(), Z.data(), J2[0], 0, 0, vp, jmax2, cos2));
  EXPECT_TRUE(continuous(X.data(), Y.data(), Z.data(), J2[0], 0, 1, vp, jmax2, cos2));  // 8 mm across the ray
  EXPECT_FALSE(
      continuous(X.data(), Y.data(), Z.data(), J2[0], 0, 2, vp, jmax2, cos2));  // 10 mm along the ray
  EXPECT_FALSE(continuous(X.data(), Y.data(), Z.data(), J2[0], 0, 3, vp, jmax2, cos2));  // no data
  EXPECT_FALSE(continuous(X.data(), Y.data(), Z.data(), J2[3], 3, 0, vp, jmax2, cos2));
  EXPECT_TRUE(
      continuous(X.data(), Y.data(), Z.data(), 10.5f * 10.5f, 0, 2, vp, jmax2, cos2));  // a raised floor
  Y[1] = 30.f;  // beyond jump_max even across the ray
  EXPECT_FALSE(continuous(X.data(), Y.data(), Z.data(), J2[0], 0, 1, vp, jmax2, cos2));
}

TEST(GridKernels, SeedsNeedAgreeingNormalsAndContinuousNeighbours) {
  Grid g(6, 3, 0.f, 0.f, 0.f, 1.f);
  const std::size_t n = g.X.size(), W = std::size_t(g.w), b = W;  // row 1
  std::vector<float> NX(n, 0.f), NY(n, 0.f), NZ(n, 1.f);
  std::vector<std::uint8_t> CT(n, 0);
  NX[g.at(0, 4)] = 0.5f;  // cell (1,4): its upper neighbour's normal is 27 deg off
  NZ[g.at(0, 4)] = std::sqrt(0.75f);
  g.Z[g.at(1, 2)] = 50.f;  // cell (1,2) is cut off by a jump (along the ray: viewpoint above)
  cont_seeds_row_fast(g.X.data() + b, g.Y.data() + b, g.Z.data() + b, g.J2.data() + b, 0.f, 0.f,
                      NX.data() + b, NY.data() + b, NZ.data() + b, 1, g.w - 1, W, {2.5f, 1.f, 500.f},
                      25.f * 25.f, 0.99f, std::cos(0.1f), CT.data() + b);
  const std::uint8_t all = kContL | kContR | kContU | kContD;
  EXPECT_EQ(CT[b + 1], std::uint8_t(kContL | kContU | kContD));  // not toward (1,2)
  EXPECT_EQ(CT[b + 2], 0);
  EXPECT_EQ(CT[b + 3], std::uint8_t(kContR | kContU | kContD));
  EXPECT_EQ(CT[b + 4], std::uint8_t(all));  // continuous, but the normals disagree
  EXPECT_EQ(CT[b + 0], 0);                  // outside [c0, c1): untouched
  Grid flat(6, 3, 0.f, 0.f, 0.f, 1.f);
  std::vector<float> nz(n, 1.f), nx(n, 0.f);
  cont_seeds_row_fast(flat.X.data() + b, flat.Y.data() + b, flat.Z.data() + b, flat.J2.data() + b, 0.f, 0.f,
                      nx.data() + b, nx.data() + b, nz.data() + b, 1, flat.w - 1, W, {2.5f, 1.f, 500.f},
                      25.f * 25.f, 0.99f, std::cos(0.1f), CT.data() + b);
  for (int k = 1; k < flat.w - 1; ++k) EXPECT_EQ(CT[b + std::size_t(k)], std::uint8_t(all | kContSeed)) << k;
}

}  // namespace
