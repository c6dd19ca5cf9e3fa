// Region moments and plane fits shared by the segmenter stages (growth, refinement, merge, final regions).
#include "host/segment/segmenter.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "host/segment/segmenter_impl.hpp"

namespace fs::host::seg {

using namespace detail;

void Segmenter::Acc::add(const Eigen::Vector3d& p, double a, double col, double row) {
  n += 1;
  sx += p.x();
  sy += p.y();
  sz += p.z();
  sxx += p.x() * p.x();
  sxy += p.x() * p.y();
  sxz += p.x() * p.z();
  syy += p.y() * p.y();
  syz += p.y() * p.z();
  szz += p.z() * p.z();
  area += a;
  pc += col;
  pr += row;
}

void Segmenter::Acc::merge(const Acc& o) {
  n += o.n;
  sx += o.sx;
  sy += o.sy;
  sz += o.sz;
  sxx += o.sxx;
  sxy += o.sxy;
  sxz += o.sxz;
  syy += o.syy;
  syz += o.syz;
  szz += o.szz;
  area += o.area;
  pc += o.pc;
  pr += o.pr;
}

void Segmenter::fit(const Acc& a, Eigen::Vector3d& n, Eigen::Vector3d& c, double& rms) const {
  const double inv = 1.0 / std::max(1.0, a.n);
  const Eigen::Vector3d m(a.sx * inv, a.sy * inv, a.sz * inv);
  Eigen::Matrix3d C;
  C(0, 0) = a.sxx * inv - m.x() * m.x();
  C(0, 1) = C(1, 0) = a.sxy * inv - m.x() * m.y();
  C(0, 2) = C(2, 0) = a.sxz * inv - m.x() * m.z();
  C(1, 1) = a.syy * inv - m.y() * m.y();
  C(1, 2) = C(2, 1) = a.syz * inv - m.y() * m.z();
  C(2, 2) = a.szz * inv - m.z() * m.z();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(C);
  n = es.eigenvectors().col(0).normalized();
  c = m + origin_;
  if (n.dot(viewpoint_ - c) < 0.0) n = -n;
  rms = std::sqrt(std::max(0.0, es.eigenvalues()(0)));
}

void Segmenter::refit(int region) {
  Eigen::Vector3d n, c;
  double rms = 0;
  fit(acc_[std::size_t(region)], n, c, rms);
  plane_[std::size_t(region)].n = n.cast<float>();
  plane_[std::size_t(region)].c = c.cast<float>();
}

void Segmenter::accumulate(Acc& a, const std::uint32_t* cells, std::size_t count) const {
  const float* X = px_.data();
  const float* Y = py_.data();
  const float* Z = pz_.data();
  const double ox = origin_.x(), oy = origin_.y(), oz = origin_.z();
  double sx = 0, sy = 0, sz = 0, sxx = 0, sxy = 0, sxz = 0, syy = 0, syz = 0, szz = 0;
  for (std::size_t q = 0; q < count; ++q) {
    const std::size_t i = cells[q];
    const double x = double(X[i]) - ox, y = double(Y[i]) - oy, z = double(Z[i]) - oz;
    sx += x;
    sy += y;
    sz += z;
    sxx += x * x;
    sxy += x * y;
    sxz += x * z;
    syy += y * y;
    syz += y * z;
    szz += z * z;
  }
  a.n += double(count);
  a.sx += sx;
  a.sy += sy;
  a.sz += sz;
  a.sxx += sxx;
  a.sxy += sxy;
  a.sxz += sxz;
  a.syy += syy;
  a.syz += syz;
  a.szz += szz;
}

void Segmenter::accumulate_run(Acc& a, std::size_t first, std::size_t last) const {
  const float* X = px_.data();
  const float* Y = py_.data();
  const float* Z = pz_.data();
  const double ox = origin_.x(), oy = origin_.y(), oz = origin_.z();
  double sx = 0, sy = 0, sz = 0, sxx = 0, sxy = 0, sxz = 0, syy = 0, syz = 0, szz = 0;
  for (std::size_t i = first; i <= last; ++i) {
    const double x = double(X[i]) - ox, y = double(Y[i]) - oy, z = double(Z[i]) - oz;
    sx += x;
    sy += y;
    sz += z;
    sxx += x * x;
    sxy += x * y;
    sxz += x * z;
    syy += y * y;
    syz += y * z;
    szz += z * z;
  }
  a.n += double(last + 1 - first);
  a.sx += sx;
  a.sy += sy;
  a.sz += sz;
  a.sxx += sxx;
  a.sxy += sxy;
  a.sxz += sxz;
  a.syy += syy;
  a.syz += syz;
  a.szz += szz;
}

}  // namespace fs::host::seg
