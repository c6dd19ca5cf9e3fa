#include "host/match/rotation_fit.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
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

void add_pair(Mat4& B, const Vec3& r, const Vec3& s, double gamma) { B.noalias() += gamma * quaternion_pair_matrix(r, s); }

RotationFit solve_rotation(const Mat4& B) {
  Eigen::SelfAdjointEigenSolver<Mat4> es(B);   // eigenvalues ascending
  const Eigen::Vector4d p = es.eigenvectors().col(0);
  Eigen::Quaterniond q(p(3), p(0), p(1), p(2));   // (w, x, y, z) from P = (x, y, z, w)
  q.normalize();
  RotationFit f;
  f.R = q.toRotationMatrix();
  f.lambda_min = std::max(0.0, es.eigenvalues()(0));
  f.lambda_gap = es.eigenvalues()(1) - es.eigenvalues()(0);
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
