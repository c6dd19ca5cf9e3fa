#include "host/match/rotation_fit.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SVD>

namespace fs::host::match {

Mat4 quaternion_pair_matrix(const Vec3& r, const Vec3& s) {
  const double rx = r.x(), ry = r.y(), rz = r.z(), sx = s.x(), sy = s.y(), sz = s.z();
  auto sq = [](double v) { return v * v; };
  Mat4 A;
  A(0, 0) = sq(rx - sx) + sq(ry + sy) + sq(rz + sz);
  A(1, 1) = sq(rx + sx) + sq(ry - sy) + sq(rz + sz);
  A(2, 2) = sq(rx + sx) + sq(ry + sy) + sq(rz - sz);
  A(3, 3) = sq(rx - sx) + sq(ry - sy) + sq(rz - sz);
  A(0, 1) = A(1, 0) = -2.0 * (rx * sy + ry * sx);
  A(1, 2) = A(2, 1) = -2.0 * (ry * sz + rz * sy);
  A(0, 2) = A(2, 0) = -2.0 * (rx * sz + rz * sx);
  A(0, 3) = A(3, 0) = 2.0 * (rz * sy - ry * sz);
  A(1, 3) = A(3, 1) = 2.0 * (rx * sz - rz * sx);
  A(2, 3) = A(3, 2) = 2.0 * (ry * sx - rx * sy);
  return A;
}

void add_pair(Mat4& B, const Vec3& r, const Vec3& s, double gamma) {
  B.noalias() += gamma * quaternion_pair_matrix(r, s);
}

RotationFit solve_rotation(const Mat4& B) {
  Eigen::SelfAdjointEigenSolver<Mat4> es(B);  // eigenvalues ascending
  const Eigen::Vector4d p = es.eigenvectors().col(0);
  Eigen::Quaterniond q(p(3), p(0), p(1), p(2));  // (w, x, y, z) from P = (x, y, z, w)
  q.normalize();
  RotationFit f;
  f.R = q.toRotationMatrix();
  f.q = Eigen::Vector4d(q.x(), q.y(), q.z(), q.w());
  f.lambda_min = std::max(0.0, es.eigenvalues()(0));
  f.lambda_gap = es.eigenvalues()(1) - es.eigenvalues()(0);
  return f;
}

namespace {

double minor3(const Mat4& M, int i, int j, int k) {
  const double a = M(i, i), b = M(i, j), c = M(i, k), d = M(j, j), e = M(j, k), f = M(k, k);
  return a * (d * f - e * e) - b * (b * f - e * c) + c * (b * e - d * c);
}

}  // namespace

Eigen::Vector4d rotation_quaternion(const Mat3& R) {
  const Eigen::Quaterniond q(R);
  return Eigen::Vector4d(q.x(), q.y(), q.z(), q.w());
}

RotationFit solve_rotation_fast(const Mat4& B, double lambda_lower, const Eigen::Vector4d& hint,
                                FastFitStats* stats) {
  auto fallback = [&] {
    if (stats) ++stats->fallback;
    return solve_rotation(B);
  };
  const double tr = B.trace();
  if (!(tr > 0) || !std::isfinite(tr)) return fallback();
  // Characteristic polynomial p(l) = l^4 - c3 l^3 + c2 l^2 - c1 l + c0 (principal minors).
  const double c3 = tr;
  double c2 = 0;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) c2 += B(i, i) * B(j, j) - B(i, j) * B(i, j);
  const double c1 = minor3(B, 0, 1, 2) + minor3(B, 0, 1, 3) + minor3(B, 0, 2, 3) + minor3(B, 1, 2, 3);
  const double c0 = B.determinant();
  auto poly = [&](double l, double& dp) {
    dp = ((4.0 * l - 3.0 * c3) * l + 2.0 * c2) * l - c1;
    return (((l - c3) * l + c2) * l - c1) * l + c0;
  };
  // Newton from below: monotone increasing towards the smallest root.
  double l = std::max(0.0, std::min(lambda_lower, tr));
  double dp = 0;
  bool converged = false;
  for (int it = 0; it < 40; ++it) {
    const double pv = poly(l, dp);
    if (!(dp < 0)) break;  // at / beyond a root or a stationary point: let the checks below decide
    const double step = -pv / dp;
    if (!(step > 1e-15 * tr)) {  // converged to rounding level (or a slightly negative step from rounding)
      converged = true;
      break;
    }
    l += step;
    if (l > tr) return fallback();
  }
  if (!converged) {
    // dp >= 0 here means l is (to rounding) at the root; accept only if p(l) is tiny.
    const double pv = poly(l, dp);
    if (!(std::abs(pv) <= 1e-12 * tr * tr * tr * tr)) return fallback();
  }
  poly(l, dp);
  const double gap_lb = std::abs(dp) / (tr * tr);
  if (!(gap_lb >= 1e-6 * tr)) return fallback();
  // Shifted inverse iteration: shift below the root by much less than the gap.
  const double sigma = l - 1e-11 * tr;
  Mat4 M = B;
  M.diagonal().array() -= sigma;
  const Eigen::PartialPivLU<Mat4> lu(M);
  Eigen::Vector4d v = hint;
  if (!v.allFinite() || !(v.squaredNorm() > 0.25)) v = Eigen::Vector4d(0.5, 0.5, 0.5, 0.5);
  // A small generic component: symmetric data can make the hint exactly orthogonal to the answer (e.g. the
  // identity vs a half turn), which inverse iteration could never leave.
  v = v.normalized() + 1e-3 * Eigen::Vector4d(0.3104, -0.5227, 0.7331, 0.1185);
  v.normalize();
  for (int it = 0; it < 5; ++it) {
    Eigen::Vector4d w = lu.solve(v);
    if (!w.allFinite() || !(w.squaredNorm() > 0)) return fallback();
    // Keep the hint's sign so consecutive states give close quaternions.
    if (w.dot(v) < 0) w = -w;
    w.normalize();
    const double change = (w - v).squaredNorm();
    v = w;
    if (it >= 1 && change < 1e-26) break;
  }
  const Eigen::Vector4d Bv = B * v;
  const double lam = v.dot(Bv);
  // Davis-Kahan: the eigenvector error is at most residual / gap; accept only a 1e-10 rad bound.
  if (!((Bv - lam * v).norm() <= 1e-10 * gap_lb)) return fallback();
  // The eigenpair must be the one of the Newton root (the smallest), not the next one (>= root + gap).
  if (!(std::abs(lam - l) <= 0.25 * gap_lb)) return fallback();
  if (stats) ++stats->fast;
  Eigen::Quaterniond q(v(3), v(0), v(1), v(2));
  q.normalize();
  RotationFit f;
  f.R = q.toRotationMatrix();
  f.q = Eigen::Vector4d(q.x(), q.y(), q.z(), q.w());
  f.lambda_min = std::max(0.0, lam);
  f.lambda_gap = gap_lb;
  return f;
}

TwoPairFit two_pair_fit(const Vec3& r1, const Vec3& s1, double g1, const Vec3& r2, const Vec3& s2,
                        double g2) {
  TwoPairFit f;
  const Vec3 sxs = s1.cross(s2);
  const double car = r1.dot(r2), sar = r1.cross(r2).norm(), cas = s1.dot(s2), sas = sxs.norm();
  if (!(sas > 1e-6)) return f;
  const double cd = cas * car + sas * sar, sd = sas * car - cas * sar;
  const double x = g1 + g2 * cd, y = g2 * sd, rho = std::sqrt(x * x + y * y);
  const double cs = cas * car - sas * sar, ss = sas * car + cas * sar;
  const double rho2 = std::sqrt((g1 + g2 * cs) * (g1 + g2 * cs) + g2 * ss * g2 * ss);
  if (!(2.0 * (rho - rho2) >= 1e-4 * (g1 + g2))) return f;
  const Vec3 b3 = sxs / sas;
  const Vec3 f2 = b3.cross(s1);
  const double cp = x / rho, sp = y / rho;
  f.Rr1 = cp * s1 + sp * f2;
  f.Rr2 = (car * cp - sar * sp) * s1 + (sar * cp + car * sp) * f2;
  f.lambda = std::max(0.0, 2.0 * (g1 + g2 - rho));
  f.ok = true;
  return f;
}

Mat3 kabsch_rotation(std::span<const Vec3> r, std::span<const Vec3> s, std::span<const double> w) {
  Mat3 H = Mat3::Zero();
  for (std::size_t i = 0; i < r.size(); ++i) H += w[i] * r[i] * s[i].transpose();
  Eigen::JacobiSVD<Mat3> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Mat3 U = svd.matrixU(), V = svd.matrixV();
  Mat3 D = Mat3::Identity();
  D(2, 2) = (V * U.transpose()).determinant() < 0 ? -1.0 : 1.0;
  return V * D * U.transpose();
}

double fit_error(const Mat3& R, std::span<const Vec3> r, std::span<const Vec3> s, std::span<const double> w) {
  double e = 0;
  for (std::size_t i = 0; i < r.size(); ++i) e += w[i] * (R * r[i] - s[i]).squaredNorm();
  return e;
}

double rotation_angle_deg(const Mat3& Ra, const Mat3& Rb) {
  // Via the quaternion (accurate for tiny angles, unlike acos of the trace).
  const Eigen::Quaterniond q(Mat3(Ra.transpose() * Rb));
  return 2.0 * std::atan2(q.vec().norm(), std::abs(q.w())) * 180.0 / std::numbers::pi;
}

}  // namespace fs::host::match
