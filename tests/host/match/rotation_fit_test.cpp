// Rotation fit (ch. 7.5, table 7.14) against an independent weighted Kabsch (SVD) solution.
#include <gtest/gtest.h>

#include <random>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <vector>

#include "host/match/rotation_fit.hpp"
#include "test_graphs.hpp"

namespace {

using namespace fs::host::match;
using fs::Mat3;
using fs::Vec3;

struct Data {
  std::vector<Vec3> r, s;
  std::vector<double> w;
};

Data make(std::mt19937& rng, const Mat3& R, int n, double noise_deg) {
  std::normal_distribution<double> nd;
  std::uniform_real_distribution<double> area(10, 1000);
  Data d;
  for (int i = 0; i < n; ++i) {
    Vec3 r = Vec3(nd(rng), nd(rng), nd(rng)).normalized();
    d.r.push_back(r);
    d.s.push_back(fs::test::tilt(R * r, noise_deg, rng));
    d.w.push_back(std::sqrt(area(rng) * area(rng)));
  }
  return d;
}

Mat4 accumulate(const Data& d) {
  Mat4 B = Mat4::Zero();
  for (std::size_t i = 0; i < d.r.size(); ++i) add_pair(B, d.r[i], d.s[i], d.w[i]);
  return B;
}

TEST(RotationFit, TableCoefficientsGiveTheQuadraticForm) {
  // P^t A P == |q r - s q|^2 for unit q (P = x y z w) and exact pairs give A P = 0 for the true rotation.
  std::mt19937 rng(1);
  for (int t = 0; t < 50; ++t) {
    const Mat3 R = fs::test::random_rotation(rng);
    Data d = make(rng, R, 1, 0);
    const Mat4 A = quaternion_pair_matrix(d.r[0], d.s[0]);
    EXPECT_LT((A - A.transpose()).norm(), 1e-15);
    Eigen::Quaterniond q(R);
    Eigen::Vector4d P(q.x(), q.y(), q.z(), q.w());
    EXPECT_NEAR(P.dot(A * P), 0.0, 1e-12);
  }
}

TEST(RotationFit, MatchesKabschOnExactData) {
  std::mt19937 rng(42);
  for (int t = 0; t < 200; ++t) {
    const Mat3 R = fs::test::random_rotation(rng);
    const Data d = make(rng, R, 2 + t % 6, 0.0);
    const RotationFit f = solve_rotation(accumulate(d));
    const Mat3 K = kabsch_rotation(d.r, d.s, d.w);
    EXPECT_LT((f.R - K).cwiseAbs().maxCoeff(), 1e-9) << "trial " << t;
    EXPECT_LT((f.R - R).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_NEAR(f.lambda_min, 0.0, 1e-9);
    EXPECT_NEAR(f.R.determinant(), 1.0, 1e-12);
  }
}

TEST(RotationFit, SameErrorAsKabschOnNoisyData) {
  std::mt19937 rng(7);
  for (int t = 0; t < 200; ++t) {
    const Mat3 R = fs::test::random_rotation(rng);
    const Data d = make(rng, R, 3 + t % 5, 5.0);
    const RotationFit f = solve_rotation(accumulate(d));
    const Mat3 K = kabsch_rotation(d.r, d.s, d.w);
    const double ek = fit_error(K, d.r, d.s, d.w);
    // lambda_min is the weighted squared error of the quaternion rotation, equal to Kabsch's optimum.
    EXPECT_NEAR(f.lambda_min, ek, 1e-9 * (1 + ek));
    EXPECT_NEAR(fit_error(f.R, d.r, d.s, d.w), ek, 1e-9 * (1 + ek));
    EXPECT_LT(rotation_angle_deg(f.R, K), 1e-6);
    EXPECT_GT(f.lambda_min, 0.0);  // noise: a non-zero error
  }
}

TEST(RotationFit, IncrementalEqualsBatch) {
  std::mt19937 rng(3);
  const Mat3 R = fs::test::random_rotation(rng);
  const Data d = make(rng, R, 6, 2.0);
  Mat4 B = Mat4::Zero();
  for (std::size_t n = 0; n < d.r.size(); ++n) {
    add_pair(B, d.r[n], d.s[n], d.w[n]);  // B_n = B_{n-1} + gamma_n A_n
    if (n == 0) continue;
    Data prefix{{d.r.begin(), d.r.begin() + static_cast<long>(n + 1)},
                {d.s.begin(), d.s.begin() + static_cast<long>(n + 1)},
                {d.w.begin(), d.w.begin() + static_cast<long>(n + 1)}};
    EXPECT_LT(rotation_angle_deg(solve_rotation(B).R, kabsch_rotation(prefix.r, prefix.s, prefix.w)), 1e-6);
  }
}

// Fast path (Newton on det(B - l I) + warm-started inverse iteration) vs the full eigen solver on random
// incremental sequences B_n = B_{n-1} + gamma_n A_n, warm-started as the matcher does (parent's lambda and
// quaternion), with exact, noisy and grossly wrong pairs.
TEST(RotationFit, FastPathEqualsFullSolverOnIncrementalSequences) {
  std::mt19937 rng(11);
  FastFitStats stats;
  int compared = 0;
  for (int t = 0; t < 400; ++t) {
    const Mat3 R = fs::test::random_rotation(rng);
    const double noise = t % 4 == 0 ? 0.0 : (t % 4 == 1 ? 1.0 : (t % 4 == 2 ? 10.0 : 90.0));
    const Data d = make(rng, R, 2 + t % 7, noise);
    Mat4 B = Mat4::Zero();
    add_pair(B, d.r[0], d.s[0], d.w[0]);
    const Eigen::Quaterniond q1 = Eigen::Quaterniond::FromTwoVectors(d.r[0], d.s[0]);
    Eigen::Vector4d hint(q1.x(), q1.y(), q1.z(), q1.w());
    double lower = 0;
    for (std::size_t n = 1; n < d.r.size(); ++n) {
      add_pair(B, d.r[n], d.s[n], d.w[n]);
      const RotationFit full = solve_rotation(B);
      const RotationFit fast = solve_rotation_fast(B, lower, hint, &stats);
      const double scale = B.trace();
      EXPECT_NEAR(fast.lambda_min, full.lambda_min, 1e-9 * full.lambda_min + 1e-13 * scale) << t << " " << n;
      EXPECT_LT((fast.R - full.R).cwiseAbs().maxCoeff(), 1e-9) << t << " " << n;
      EXPECT_NEAR(fast.R.determinant(), 1.0, 1e-12);
      EXPECT_LE(fast.lambda_gap, full.lambda_gap * (1 + 1e-9) + 1e-13 * scale);  // a lower bound
      EXPECT_GE(fast.lambda_min, lower * (1 - 1e-9) - 1e-13 * scale);            // Weyl: monotone
      lower = fast.lambda_min;
      hint = fast.q;
      ++compared;
    }
  }
  EXPECT_GT(compared, 1000);
  // Nearly all of them take the fast path (the point of it); the rest fell back and are exact by
  // construction.
  EXPECT_GT(stats.fast, compared * 9 / 10) << "fallbacks " << stats.fallback;
}

TEST(RotationFit, FastPathWithoutWarmStartFindsTheSmallestEigenpair) {
  // A bad hint (orthogonal to the answer) and a zero lower bound: Newton from below still finds the smallest
  // root and the inverse iteration converges to its eigenvector.
  std::mt19937 rng(5);
  for (int t = 0; t < 100; ++t) {
    const Mat3 R = fs::test::random_rotation(rng);
    const Data d = make(rng, R, 3 + t % 4, 3.0);
    const Mat4 B = accumulate(d);
    const RotationFit full = solve_rotation(B);
    Eigen::Vector4d hint = Eigen::Vector4d::Zero();
    hint(t % 4) = 1.0;
    hint -= hint.dot(full.q) * full.q;
    const RotationFit fast = solve_rotation_fast(B, 0.0, hint);
    EXPECT_NEAR(fast.lambda_min, full.lambda_min, 1e-9 * full.lambda_min + 1e-13 * B.trace());
    EXPECT_LT(rotation_angle_deg(fast.R, full.R), 1e-7);
    // Hint = exactly another eigenvector (happens with symmetric exact data, e.g. cube corners).
    const Eigen::SelfAdjointEigenSolver<Mat4> es(B);
    const RotationFit fast2 = solve_rotation_fast(B, 0.0, es.eigenvectors().col(1 + t % 3));
    EXPECT_NEAR(fast2.lambda_min, full.lambda_min, 1e-9 * full.lambda_min + 1e-13 * B.trace());
    EXPECT_LT(rotation_angle_deg(fast2.R, full.R), 1e-7);
  }
}

TEST(RotationFit, FastPathFallsBackOnDegenerateSets) {
  // Parallel normals: a one-parameter family of rotations (gap 0) -> the full solver's answer.
  Mat4 B = Mat4::Zero();
  add_pair(B, Vec3::UnitX(), Vec3::UnitY(), 1.0);
  add_pair(B, Vec3::UnitX(), Vec3::UnitY(), 2.0);
  FastFitStats stats;
  const RotationFit fast = solve_rotation_fast(B, 0.0, Eigen::Vector4d(0, 0, 0, 1), &stats);
  const RotationFit full = solve_rotation(B);
  EXPECT_EQ(stats.fallback, 1);
  EXPECT_EQ(stats.fast, 0);
  EXPECT_EQ(fast.R, full.R);
  EXPECT_EQ(fast.lambda_min, full.lambda_min);
  // Zero matrix and non-finite input: fallback, no crash.
  stats = {};
  solve_rotation_fast(Mat4::Zero(), 0.0, Eigen::Vector4d(0, 0, 0, 1), &stats);
  EXPECT_EQ(stats.fallback, 1);
}

TEST(RotationFit, DegenerateSingleNormalHasZeroGap) {
  Mat4 B = Mat4::Zero();
  add_pair(B, Vec3::UnitX(), Vec3::UnitY(), 1.0);
  const RotationFit f = solve_rotation(B);
  EXPECT_NEAR(f.lambda_gap, 0.0, 1e-12);  // a one-parameter family of rotations
  EXPECT_LT((f.R * Vec3::UnitX() - Vec3::UnitY()).norm(), 1e-12);
}

}  // namespace

namespace {

// The closed-form two-pair fit (used by the matcher's level-2 visibility check) against the eigen solver on
// random pairs: exact, 1-20 degrees of noise, arbitrary (unrelated) scene normals, near-parallel normals.
TEST(RotationFit, TwoPairClosedFormEqualsEigenSolver) {
  std::mt19937 rng(404);
  std::normal_distribution<double> nd;
  std::uniform_real_distribution<double> area(10, 1000), noise(1, 20);
  int ok = 0, refused = 0;
  for (int it = 0; it < 3000; ++it) {
    const Mat3 R = fs::test::random_rotation(rng);
    const Vec3 r1 = Vec3(nd(rng), nd(rng), nd(rng)).normalized();
    Vec3 r2 = Vec3(nd(rng), nd(rng), nd(rng)).normalized();
    if (it % 10 == 0) r2 = fs::test::tilt(r1, 0.5, rng);  // nearly parallel reference normals
    Vec3 s1, s2;
    switch (it % 4) {
      case 0:
        s1 = R * r1;
        s2 = R * r2;
        break;  // exact
      case 1:
        s1 = fs::test::tilt(R * r1, noise(rng), rng);
        s2 = fs::test::tilt(R * r2, noise(rng), rng);
        break;
      case 2:
        s1 = Vec3(nd(rng), nd(rng), nd(rng)).normalized();
        s2 = Vec3(nd(rng), nd(rng), nd(rng)).normalized();
        break;
      default:
        s1 = R * r1;
        s2 = fs::test::tilt(s1, 0.3, rng);
        break;  // parallel-ish scene
    }
    const double g1 = std::sqrt(area(rng) * area(rng)), g2 = std::sqrt(area(rng) * area(rng));
    Mat4 B = Mat4::Zero();
    add_pair(B, r1, s1, g1);
    add_pair(B, r2, s2, g2);
    const TwoPairFit tp = two_pair_fit(r1, s1, g1, r2, s2, g2);
    const Eigen::SelfAdjointEigenSolver<Mat4> es(B);
    const double tr = B.trace();
    if (!tp.ok) {
      ++refused;
      continue;
    }
    ++ok;
    // Refused cases aside, the gap is at least the promised 1.25e-5 trace B.
    EXPECT_GE(es.eigenvalues()(1) - es.eigenvalues()(0), 1.2e-5 * tr) << it;
    const RotationFit f = solve_rotation(B);
    EXPECT_NEAR(tp.lambda, f.lambda_min, 1e-11 * tr) << it;
    EXPECT_LT((f.R * r1 - tp.Rr1).norm(), 1e-9) << it;
    EXPECT_LT((f.R * r2 - tp.Rr2).norm(), 1e-9) << it;
  }
  EXPECT_GT(ok, 2000);
  EXPECT_GT(refused, 0);
}

TEST(RotationFit, TwoPairClosedFormRefusesParallelSceneNormals) {
  const Vec3 r1(1, 0, 0), r2(0, 1, 0), s(0, 0, 1);
  EXPECT_FALSE(two_pair_fit(r1, s, 10.0, r2, s, 10.0).ok);
  // Nearly antiparallel scene normals: the rotation about s1 is almost free (eigen gap ~1e-5 of the bound).
  const Vec3 s1(1, 0, 0), s2(-1, 1e-5, 0);
  EXPECT_FALSE(two_pair_fit(r1, s1, 10.0, r2, s2.normalized(), 10.0).ok);
}

}  // namespace
