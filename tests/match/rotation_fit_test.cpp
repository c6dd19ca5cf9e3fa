// Rotation fit (ch. 7.5, table 7.14) against an independent weighted Kabsch (SVD) solution.
#include <gtest/gtest.h>

#include <random>
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
    EXPECT_GT(f.lambda_min, 0.0);   // noise: a non-zero error
  }
}

TEST(RotationFit, IncrementalEqualsBatch) {
  std::mt19937 rng(3);
  const Mat3 R = fs::test::random_rotation(rng);
  const Data d = make(rng, R, 6, 2.0);
  Mat4 B = Mat4::Zero();
  for (std::size_t n = 0; n < d.r.size(); ++n) {
    add_pair(B, d.r[n], d.s[n], d.w[n]);   // B_n = B_{n-1} + gamma_n A_n
    if (n == 0) continue;
    Data prefix{{d.r.begin(), d.r.begin() + static_cast<long>(n + 1)},
                {d.s.begin(), d.s.begin() + static_cast<long>(n + 1)},
                {d.w.begin(), d.w.begin() + static_cast<long>(n + 1)}};
    EXPECT_LT(rotation_angle_deg(solve_rotation(B).R, kabsch_rotation(prefix.r, prefix.s, prefix.w)), 1e-6);
  }
}

TEST(RotationFit, DegenerateSingleNormalHasZeroGap) {
  Mat4 B = Mat4::Zero();
  add_pair(B, Vec3::UnitX(), Vec3::UnitY(), 1.0);
  const RotationFit f = solve_rotation(B);
  EXPECT_NEAR(f.lambda_gap, 0.0, 1e-12);   // a one-parameter family of rotations
  EXPECT_LT((f.R * Vec3::UnitX() - Vec3::UnitY()).norm(), 1e-12);
}

}  // namespace
