#pragma once
// Rotation fitting (thesis ch. 7.5): the weighted Horn/Davenport quaternion method. Each normal pair (r, s)
// (reference, scene) contributes gamma * A(r, s) (table 7.14) to the symmetric 4x4 matrix B; the best
// rotation R (R r ~ s) is the eigenvector of B's smallest eigenvalue, which equals sum gamma |R r - s|^2.
// Quaternion component order of table 7.14: P = (x, y, z, w).
#include <span>

#include <Eigen/Core>

#include "common/calibration.hpp"

namespace fs::host::match {

using Mat4 = Eigen::Matrix4d;

// Table 7.14: the coefficients of A for one pair of unit normals (r reference, s scene).
Mat4 quaternion_pair_matrix(const Vec3& r, const Vec3& s);

// Adds gamma * A(r, s) to B (B_n = B_{n-1} + gamma_n A_n).
void add_pair(Mat4& B, const Vec3& r, const Vec3& s, double gamma);

struct RotationFit {
  Mat3 R = Mat3::Identity();      // maps reference normals onto scene normals
  double lambda_min = 0.0;        // weighted squared error sum gamma |R r - s|^2 (clamped >= 0)
  double lambda_gap = 0.0;        // second smallest minus smallest eigenvalue
  Eigen::Vector4d q{0, 0, 0, 1};  // unit quaternion of R, P = (x, y, z, w) (the eigenvector, sign arbitrary)
};

// Minimizes P^t B P with Eigen's SelfAdjointEigenSolver (no heap allocation).
RotationFit solve_rotation(const Mat4& B);

// Same answer as solve_rotation, much cheaper (used once per search state):
//  1. Newton on the characteristic polynomial det(B - l I) from a lower bound of the smallest eigenvalue
//     (B is positive semi-definite, and B_n = B_{n-1} + gamma A_n with A_n PSD, so the parent's lambda_min is
//     a lower bound, Weyl): the iterates increase monotonically to the smallest root, never to another one;
//  2. two steps of shifted inverse iteration (shift just below that root), warm-started from the hint
//     (the parent's quaternion), then the Rayleigh quotient as lambda_min.
// Falls back to solve_rotation when Newton does not converge, the residual check fails, or the eigen gap is
// tiny (gap < 1e-6 trace(B): degenerate normal sets, where the eigenvector is ill-defined).
// lambda_gap: on the fast path a lower bound of the gap, |p'(lambda_min)| / trace(B)^2.
struct FastFitStats {
  long fast = 0, fallback = 0;
};
RotationFit solve_rotation_fast(const Mat4& B, double lambda_lower, const Eigen::Vector4d& hint,
                                FastFitStats* stats = nullptr);

// The optimal rotation of two weighted normal pairs (r1 -> s1 weight g1, r2 -> s2 weight g2; unit normals) in
// closed form, the two-observation Wahba problem: R maps r1 x r2 onto the direction of s1 x s2 and turns
// about it by phi, tan phi = g2 sin d / (g1 + g2 cos d), d = angle(s1, s2) - angle(r1, r2). The eigenvalues
// of B are 2 (g1 + g2) -+ 2 rho and 2 (g1 + g2) -+ 2 rho', rho = |g1 + g2 e^{i d}|, rho' = |g1 + g2 e^{i
// (angle(s1, s2) + angle(r1, r2))}|: lambda_min = 2 (g1 + g2 - rho), gap to the next 2 (rho - rho'). ok =
// false (no answer) when the scene normals are parallel (|s1 x s2| <= 1e-6) or the gap is below 1e-4 (g1 +
// g2) (= 1.25e-5 trace B); otherwise solve_rotation's R r1, R r2 and lambda_min agree to ~1e-12. About 60
// flops, no eigen solve.
struct TwoPairFit {
  bool ok = false;
  Vec3 Rr1 = Vec3::Zero(), Rr2 = Vec3::Zero();  // R r1, R r2
  double lambda = 0.0;                          // lambda_min of B = g1 A(r1, s1) + g2 A(r2, s2)
};
TwoPairFit two_pair_fit(const Vec3& r1, const Vec3& s1, double g1, const Vec3& r2, const Vec3& s2, double g2);

// Unit quaternion P = (x, y, z, w) of table 7.14 for R.
Eigen::Vector4d rotation_quaternion(const Mat3& R);

// Independent check (weighted Kabsch / SVD): the rotation minimizing sum w |R r_i - s_i|^2.
Mat3 kabsch_rotation(std::span<const Vec3> r, std::span<const Vec3> s, std::span<const double> w);

// Weighted squared error sum w |R r_i - s_i|^2.
double fit_error(const Mat3& R, std::span<const Vec3> r, std::span<const Vec3> s, std::span<const double> w);

// Angle of the rotation R_a^T R_b in degrees.
double rotation_angle_deg(const Mat3& Ra, const Mat3& Rb);

}  // namespace fs::host::match
