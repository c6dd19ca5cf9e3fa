#include "host/segment/segmenter.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <Eigen/Eigenvalues>

#include "common/error.hpp"
#include "host/segment/grid_kernels.hpp"

namespace fs::host::seg {
namespace {

constexpr std::int32_t kUnassigned = -3;
constexpr std::uint8_t kValid = 1, kHasNormal = 2, kSeed = 4, kTried = 8, kQueued = 16;
// continuity bits (cont_): cell i is depth-continuous toward its left / right / upper / lower neighbour
using kernels::kContD;
using kernels::kContL;
using kernels::kContR;
using kernels::kContU;
constexpr double kPi = 3.14159265358979323846;

// Points with any non-finite coordinate carry no data (NaN = no data by contract; inf is treated alike).
bool finite(const Eigen::Vector3f& p) { return p.allFinite() && p.cwiseAbs().maxCoeff() < 1e7f; }

double cos_deg(double deg) { return std::cos(deg * kPi / 180.0); }

std::uint64_t pair_key(std::int32_t a, std::int32_t b) {
  return (std::uint64_t(std::uint32_t(a)) << 32) | std::uint32_t(b);
}

std::size_t next_pow2(std::size_t v) {
  std::size_t p = 1;
  while (p < v) p <<= 1;
  return p;
}

// The 4-neighbours of cell i in a w x h grid and their continuity bits (kContL/R/U/D); returns how many.
inline int grid_neighbours(std::size_t i, std::size_t w, std::size_t h, std::size_t nb[4],
                           std::uint8_t bit[4]) {
  const std::size_t row = i / w, col = i - row * w;
  int k = 0;
  if (col > 0) {
    nb[k] = i - 1;
    bit[k++] = kContL;
  }
  if (col + 1 < w) {
    nb[k] = i + 1;
    bit[k++] = kContR;
  }
  if (row > 0) {
    nb[k] = i - w;
    bit[k++] = kContU;
  }
  if (row + 1 < h) {
    nb[k] = i + w;
    bit[k++] = kContD;
  }
  return k;
}

}  // namespace

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

Segmenter::Segmenter(const SegmentParams& params, const SegmentLimits& limits)
    : params_(params), limits_(limits) {
  acc_.resize(limits_.max_regions);
  plane_.resize(limits_.max_regions);
  parent_.resize(limits_.max_regions);
  remap_.resize(limits_.max_regions);
  grown_.resize(limits_.max_regions);
  const std::size_t cap = next_pow2(limits_.max_borders * 2 + 16);
  bkey_.assign(cap, ~std::uint64_t{0});
  bval_.assign(cap, -1);
  line_.resize(limits_.max_borders);
  reserve(limits_.max_cells);
}

void Segmenter::reserve(std::size_t n) {
  if (area_.size() >= n) return;
  for (auto* v : {&px_, &py_, &pz_, &nx_, &ny_, &nz_}) v->resize(n);
  cont_.resize(n);
  area_.resize(n);
  lenu_.resize(n);
  lenv_.resize(n);
  jump2_.resize(n);
  dist_.resize(n);
  state_.resize(n);
  lab_.resize(n);
  queue_.resize(n);
  pend_cell_.resize(n);
  pend_label_.resize(n);
  edge_cell_.resize(2 * n + 8);
  edge_border_.resize(2 * n + 8);
  bins_.resize(n + 1024);
  noise_samples_.reserve(kNoiseSamples);
  limits_.max_cells = std::max(limits_.max_cells, n);
}

// The component of p[c-1] - 2 p[c] + p[c+1] across the local tangent p[c+1] - p[c-1]: 0 on a plane (the three
// points lie on the line where the row meets the surface, whatever their spacing), noise of variance ~6
// sigma^2 otherwise. The median over a subsample of depth-continuous triples ignores creases and edges.
double Segmenter::estimate_noise(const OrganizedCloud& cloud) {
  noise_samples_.clear();
  const std::uint32_t w = cloud.width, h = cloud.height;
  if (w < 3 || h == 0) return 0.0;
  const std::size_t per_row = w - 2;
  const std::uint32_t stride = std::max<std::uint32_t>(
      1, static_cast<std::uint32_t>((per_row * h + kNoiseSamples - 1) / kNoiseSamples));
  const float jump2 = float(params_.jump_abs_mm * params_.jump_abs_mm);
  for (std::uint32_t r = 0; r < h; r += stride) {
    const Eigen::Vector3f* row = cloud.points.data() + std::size_t(r) * w;
    for (std::uint32_t c = 1; c + 1 < w && noise_samples_.size() < kNoiseSamples; ++c) {
      const Eigen::Vector3f& a = row[c - 1];
      const Eigen::Vector3f& b = row[c];
      const Eigen::Vector3f& d = row[c + 1];
      if (!finite(a) || !finite(b) || !finite(d)) continue;
      const Eigen::Vector3f t = d - a;
      const float tt = t.squaredNorm();
      if (!(tt > 0.0f) || (b - a).squaredNorm() > jump2 || (d - b).squaredNorm() > jump2) continue;
      const Eigen::Vector3f d2 = a - 2.0f * b + d;
      noise_samples_.push_back((d2 - (d2.dot(t) / tt) * t).norm());
    }
  }
  if (noise_samples_.size() < 64) return 0.0;
  auto mid = noise_samples_.begin() + static_cast<std::ptrdiff_t>(noise_samples_.size() / 2);
  std::nth_element(noise_samples_.begin(), mid, noise_samples_.end());
  // |N(0, 6 s^2)| has median 0.6745 sqrt(6) s.
  return double(*mid) / (0.6745 * std::sqrt(6.0));
}

void Segmenter::prepare(Segmentation& out) const {
  out.reserve(limits_.max_cells, limits_.max_regions, limits_.max_borders);
}

void Segmenter::segment(const OrganizedCloud& cloud, Segmentation& out) {
  const std::size_t n = std::size_t(cloud.width) * cloud.height;
  if (cloud.points.size() != n) {
    throw Error("segment: organized cloud has " + std::to_string(cloud.points.size()) +
                " points, expected width " + std::to_string(cloud.width) + " x height " +
                std::to_string(cloud.height));
  }
  if (!cloud.viewpoint.allFinite()) throw Error("segment: viewpoint is not finite");
  reserve(n);
  width_ = cloud.width;
  height_ = cloud.height;
  viewpoint_ = cloud.viewpoint;
  vp_f_ = viewpoint_.cast<float>();
  jump_max2_ = float(params_.jump_max_mm * params_.jump_max_mm);
  const double cj = std::cos(params_.jump_angle_deg * kPi / 180.0);
  cos2_jump_ = float(cj * cj);
  out.width = cloud.width;
  out.height = cloud.height;
  out.truncated = false;
  out.regions.clear();
  out.borders.clear();
  origin_.setZero();
  for (std::size_t i = 0; i < n; ++i) {
    if (finite(cloud.points[i])) {
      origin_ = cloud.points[i].cast<double>();
      break;
    }
  }
  region_count_ = 0;
  out.noise_mm = estimate_noise(cloud);
  dist_abs_ = std::max(params_.dist_abs_mm, params_.dist_noise_factor * out.noise_mm);
  out.dist_mm = dist_abs_;
  compute_normals(cloud);
  grow_regions(cloud, out);
  refine_edges(cloud);
  merge_regions(cloud, out);
  relabel_borders(cloud);
  group_leftovers(cloud, out);
  finalize_regions(cloud, out);
  compute_borders(cloud, out);
}

void Segmenter::compute_normals(const OrganizedCloud& cloud) {
  using namespace kernels;
  const int w = int(width_), h = int(height_);
  if (w == 0 || h == 0) return;
  const std::size_t W = std::size_t(w);
  const auto& P = cloud.points;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const int span = std::max(1, params_.normal_span);
  const Viewpoint vpk{vp_f_.x(), vp_f_.y(), vp_f_.z()};
  float* X = px_.data();
  float* Y = py_.data();
  float* Z = pz_.data();
  float* NX = nx_.data();
  float* NY = ny_.data();
  float* NZ = nz_.data();
  float* AR = area_.data();
  float* LU = lenu_.data();
  float* LV = lenv_.data();
  float* J2 = jump2_.data();
  std::uint8_t* ST = state_.data();
  std::uint8_t* CT = cont_.data();
  // One streaming pass over the rows (the rows a step needs are still in cache): structure-of-arrays copy and
  // thresholds of row r, normals of row r - span (its tangents need rows up to r), continuity bits and seeds
  // of row r - span - 1 (they need the normals of the rows around them). The common interior cases run in the
  // vectorized kernels of grid_kernels.hpp; the rest (image border, missing data, depth jumps) takes the
  // scalar path with one-sided tangents.
  auto thresholds_row = [&](int r) {
    const std::size_t b = std::size_t(r) * W;
    soa_row(P[b].data(), w, vpk, float(params_.jump_abs_mm), float(params_.jump_rel), float(dist_abs_),
            float(params_.dist_rel), X + b, Y + b, Z + b, J2 + b, dist_.data() + b, ST + b);
    for (std::size_t i = b; i < b + W; ++i) lab_[i] = ST[i] ? kUnassigned : kNil;  // ST: 1 = kValid or 0
  };
  // One tangent along a grid axis: central difference over +-s cells when both sides are continuous,
  // else one-sided; tries span, then 1. Returns false when no continuous neighbour exists.
  auto tangent = [&](int r, int c, int dr, int dc, Eigen::Vector3f& t) {
    const std::size_t i = std::size_t(r) * W + std::size_t(c);
    const Eigen::Vector3f& p = P[i];
    for (int s = span; s >= 1; s = (s == 1 ? 0 : 1)) {
      const float lim = J2[i] * float(s * s);
      const int r1 = r + dr * s, c1 = c + dc * s, r0 = r - dr * s, c0 = c - dc * s;
      auto ok = [&](const Eigen::Vector3f& q) {
        const Eigen::Vector3f d = q - p;
        const float dd = d.squaredNorm();
        if (dd <= lim) return true;
        if (!(dd <= jump_max2_ * float(s * s))) return false;
        const Eigen::Vector3f ray = p - vp_f_;
        const float cr = ray.dot(d);
        return cr * cr < cos2_jump_ * dd * ray.squaredNorm();
      };
      const bool fwd = r1 < h && c1 < w && (ST[std::size_t(r1) * W + c1]) && ok(P[std::size_t(r1) * W + c1]);
      const bool bwd =
          r0 >= 0 && c0 >= 0 && (ST[std::size_t(r0) * W + c0]) && ok(P[std::size_t(r0) * W + c0]);
      if (fwd && bwd) {
        t = (P[std::size_t(r1) * W + c1] - P[std::size_t(r0) * W + c0]) / float(2 * s);
        return true;
      }
      if (fwd) {
        t = (P[std::size_t(r1) * W + c1] - p) / float(s);
        return true;
      }
      if (bwd) {
        t = (p - P[std::size_t(r0) * W + c0]) / float(s);
        return true;
      }
      if (s == 1) break;
    }
    return false;
  };
  const Eigen::Vector3f vp = vp_f_;
  auto normals_row = [&](int r) {
    const std::size_t b = std::size_t(r) * W;
    const bool inner_row = r >= span && r + span < h && w > 2 * span;
    const int c0 = inner_row ? span : 0, c1 = inner_row ? w - span : 0;
    if (inner_row) {
      normals_row_fast(X + b, Y + b, Z + b, J2 + b, c0, c1, std::size_t(span), W * std::size_t(span), vpk,
                       NX + b, NY + b, NZ + b, AR + b, LU + b, LV + b);
    }
    for (int c = 0; c < w; ++c) {
      const std::size_t i = b + std::size_t(c);
      if (c >= c0 && c < c1 && NX[i] == NX[i]) continue;  // done by the fast path
      NX[i] = NY[i] = NZ[i] = nan;
      AR[i] = LU[i] = LV[i] = 0.f;
      if (!(ST[i] & kValid)) continue;
      Eigen::Vector3f du, dv;
      const bool hu = tangent(r, c, 0, 1, du);
      const bool hv = tangent(r, c, 1, 0, dv);
      if (hu) LU[i] = du.squaredNorm();  // squared here, sqrt where borders need it
      if (hv) LV[i] = dv.squaredNorm();
      if (!hu || !hv) continue;
      Eigen::Vector3f nn = du.cross(dv);
      const float a = nn.norm();
      if (!(a > 0.f)) continue;
      nn /= a;
      if (nn.dot(vp - P[i]) < 0.f) nn = -nn;
      NX[i] = nn.x();
      NY[i] = nn.y();
      NZ[i] = nn.z();
      AR[i] = a;
    }
    for (std::size_t i = b; i < b + W; ++i) ST[i] |= NX[i] == NX[i] ? kHasNormal : 0;
  };
  // continuity bits toward the 4 neighbours, and seeds: the normal agrees with the 4 neighbours' normals
  // (within seed_angle_deg) and all 4 are depth-continuous
  const float cs = float(cos_deg(params_.seed_angle_deg));
  auto seeds_row = [&](int r) {
    const std::size_t b = std::size_t(r) * W;
    const bool inner_row = r >= 1 && r + 1 < h && w > 2;
    const int c0 = inner_row ? 1 : 0, c1 = inner_row ? w - 1 : 0;
    if (inner_row) {
      cont_seeds_row_fast(X + b, Y + b, Z + b, J2 + b, NX + b, NY + b, NZ + b, c0, c1, W, vpk, jump_max2_,
                          cos2_jump_, cs, CT + b);
    }
    for (int c = 0; c < w; ++c) {
      const std::size_t i = b + std::size_t(c);
      if (c >= c0 && c < c1) {
        ST[i] |= (CT[i] & kContSeed) ? kSeed : 0;
        CT[i] &= std::uint8_t(~kContSeed);
        continue;
      }
      std::uint8_t bits = 0;
      if (c > 0 && kernels::continuous(X, Y, Z, J2, i, i - 1, vpk, jump_max2_, cos2_jump_)) bits |= kContL;
      if (c + 1 < w && kernels::continuous(X, Y, Z, J2, i, i + 1, vpk, jump_max2_, cos2_jump_))
        bits |= kContR;
      if (r > 0 && kernels::continuous(X, Y, Z, J2, i, i - W, vpk, jump_max2_, cos2_jump_)) bits |= kContU;
      if (r + 1 < h && kernels::continuous(X, Y, Z, J2, i, i + W, vpk, jump_max2_, cos2_jump_))
        bits |= kContD;
      CT[i] = bits;
    }
  };
  for (int r = 0; r < h + span + 1; ++r) {
    if (r < h) thresholds_row(r);
    const int rn = r - span;
    if (rn >= 0 && rn < h) normals_row(rn);
    const int rs = rn - 1;
    if (rs >= 0 && rs < h) seeds_row(rs);
  }
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

// Region growing as a scanline flood fill: the region is a list of row runs [SA[k], SB[k]]; a run taken from
// the list is first extended left / right along its row, then the cells above / below it that qualify become
// new runs. Same acceptance as a cell-by-cell breadth-first growth (a neighbour joins when it is depth-
// continuous from an accepted cell - the cont_ bit, which also implies that it exists -, has a normal within
// angle_deg of the region's and lies within its distance tolerance of the region's plane), but the grid is
// read row-wise, not along a diamond-shaped front. The plane is refitted each time the region doubles. The
// first kScanlineAfter cells grow breadth-first (runs of one cell), so the early fits see a 2D patch.
void Segmenter::grow_regions(const OrganizedCloud& /*cloud*/, Segmentation& out) {
  constexpr std::size_t kScanlineAfter = 256;  // cells grown breadth-first before the runs take over
  const std::size_t w = width_, n = w * height_;
  const float* X = px_.data();
  const float* Y = py_.data();
  const float* Z = pz_.data();
  const float* NX = nx_.data();
  const float* NY = ny_.data();
  const float* NZ = nz_.data();
  const float* DI = dist_.data();
  const std::uint8_t* CT = cont_.data();
  std::int32_t* LB = lab_.data();
  std::uint32_t* SA = queue_.data();      // run starts (cell index)
  std::uint32_t* SB = pend_cell_.data();  // run ends (inclusive, same row)
  const float ca = float(cos_deg(params_.angle_deg));
  const std::size_t max_grown = limits_.max_regions;
  for (std::size_t seed = 0; seed < n; ++seed) {
    if (LB[seed] != kUnassigned || (state_[seed] & (kSeed | kTried)) != kSeed) continue;
    if (region_count_ >= max_grown) {
      out.truncated = true;
      break;
    }
    const std::int32_t r = std::int32_t(region_count_);
    Acc& acc = acc_[std::size_t(r)];
    acc = Acc{};
    PlaneF& pl = plane_[std::size_t(r)];
    pl.n = Eigen::Vector3f(NX[seed], NY[seed], NZ[seed]);
    pl.c = Eigen::Vector3f(X[seed], Y[seed], Z[seed]);
    float pnx = pl.n.x(), pny = pl.n.y(), pnz = pl.n.z(), pcx = pl.c.x(), pcy = pl.c.y(), pcz = pl.c.z();
    std::size_t cells = 0, next_refit = 8;
    auto ok = [&](std::size_t j) {
      return LB[j] == kUnassigned && NX[j] * pnx + NY[j] * pny + NZ[j] * pnz >= ca &&
             std::abs(pnx * (X[j] - pcx) + pny * (Y[j] - pcy) + pnz * (Z[j] - pcz)) <= DI[j];
    };
    auto add = [&](std::size_t first, std::size_t last) {
      accumulate_run(acc, first, last);
      cells += last + 1 - first;
      if (cells >= next_refit) {
        refit(int(r));
        pnx = pl.n.x();
        pny = pl.n.y();
        pnz = pl.n.z();
        pcx = pl.c.x();
        pcy = pl.c.y();
        pcz = pl.c.z();
        while (next_refit <= cells) next_refit *= 2;
      }
    };
    std::size_t head = 0, tail = 0;
    LB[seed] = r;
    SA[tail] = SB[tail] = std::uint32_t(seed);
    ++tail;
    add(seed, seed);
    while (head < tail) {
      if (cells < kScanlineAfter) {
        // the first cells grow breadth-first, one cell per run: a run along one row would refit the plane
        // on (nearly) collinear points
        const std::size_t i = SA[head++];
        const std::uint8_t ct = CT[i];
        const std::size_t nb[4] = {i - 1, i + 1, i - w, i + w};
        const std::uint8_t bits[4] = {kContL, kContR, kContU, kContD};
        for (int t = 0; t < 4; ++t) {
          if (!(ct & bits[t]) || !ok(nb[t])) continue;
          LB[nb[t]] = r;
          SA[tail] = SB[tail] = std::uint32_t(nb[t]);
          ++tail;
          add(nb[t], nb[t]);
        }
        continue;
      }
      const std::size_t a0 = SA[head], b0 = SB[head];
      std::size_t a = a0, b = b0;
      while ((CT[a] & kContL) && ok(a - 1)) LB[--a] = r;
      while ((CT[b] & kContR) && ok(b + 1)) LB[++b] = r;
      if (a < a0) add(a, a0 - 1);
      if (b > b0) add(b0 + 1, b);
      SA[head] = std::uint32_t(a);
      SB[head] = std::uint32_t(b);
      ++head;
      for (int side = 0; side < 2; ++side) {
        const std::uint8_t bit = side == 0 ? kContU : kContD;
        for (std::size_t k = a; k <= b; ++k) {
          if (!(CT[k] & bit)) continue;
          const std::size_t j0 = side == 0 ? k - w : k + w;
          if (!ok(j0)) continue;
          LB[j0] = r;
          std::size_t j1 = j0;
          while (k + 1 <= b && (CT[k + 1] & bit) && ok(j1 + 1)) {
            LB[++j1] = r;
            ++k;
          }
          SA[tail] = std::uint32_t(j0);
          SB[tail] = std::uint32_t(j1);
          ++tail;
          add(j0, j1);
        }
      }
    }
    if (cells < params_.min_grow_cells) {
      for (std::size_t q = 0; q < tail; ++q) {
        for (std::size_t i = SA[q]; i <= SB[q]; ++i) {
          LB[i] = kUnassigned;
          state_[i] |= kTried;
        }
      }
      continue;
    }
    refit(int(r));
    grown_[std::size_t(r)] = 1;
    ++region_count_;
  }
}

void Segmenter::refine_edges(const OrganizedCloud& cloud) {
  const std::size_t w = width_, h = height_, n = w * h;
  const auto& P = cloud.points;
  const float f = float(params_.edge_dist_factor);
  for (int pass = 0; pass < params_.refine_passes; ++pass) {
    std::size_t np = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (lab_[i] != kUnassigned) continue;
      std::size_t nb[4];
      std::uint8_t bit[4];
      const int k = grid_neighbours(i, w, h, nb, bit);
      float best = std::numeric_limits<float>::max();
      std::int32_t bl = -1;
      for (int t = 0; t < k; ++t) {
        const std::int32_t l = lab_[nb[t]];
        if (l < 0 || !(cont_[i] & bit[t])) continue;
        const PlaneF& pl = plane_[std::size_t(l)];
        const float d = std::abs(pl.n.dot(P[i] - pl.c));
        if (d <= f * dist_[i] && d < best) {
          best = d;
          bl = l;
        }
      }
      if (bl >= 0) {
        pend_cell_[np] = std::uint32_t(i);
        pend_label_[np] = bl;
        ++np;
      }
    }
    if (np == 0) break;
    for (std::size_t q = 0; q < np; ++q) {
      lab_[pend_cell_[q]] = pend_label_[q];
      accumulate(acc_[std::size_t(pend_label_[q])], &pend_cell_[q], 1);
    }
  }
  for (std::size_t r = 0; r < region_count_; ++r) refit(int(r));
}

void Segmenter::clear_border_table() { std::fill(bkey_.begin(), bkey_.end(), ~std::uint64_t{0}); }

int Segmenter::border_slot(Segmentation& out, std::int32_t a, std::int32_t b) {
  const std::uint64_t key = pair_key(a, b);
  const std::size_t mask = bkey_.size() - 1;
  std::size_t s = std::size_t((key * 0x9E3779B97F4A7C15ull) >> 17) & mask;
  while (true) {
    if (bkey_[s] == key) return bval_[s];
    if (bkey_[s] == ~std::uint64_t{0}) break;
    s = (s + 1) & mask;
  }
  if (out.borders.size() >= limits_.max_borders) {
    out.truncated = true;
    return -1;
  }
  bkey_[s] = key;
  bval_[s] = int(out.borders.size());
  Border bd;
  bd.a = a;
  bd.b = b;
  out.borders.push_back(bd);
  return bval_[s];
}

void Segmenter::merge_regions(const OrganizedCloud& /*cloud*/, Segmentation& out) {
  const std::size_t w = width_, h = height_;
  const std::size_t R = region_count_;
  for (std::size_t r = 0; r < R; ++r) parent_[r] = std::int32_t(r);
  // adjacency of grown regions through depth-continuous cell pairs (reuses the border table)
  clear_border_table();
  out.borders.clear();
  for (std::size_t row = 0; row < h; ++row) {
    for (std::size_t col = 0; col < w; ++col) {
      const std::size_t i = row * w + col;
      const std::int32_t li = lab_[i];
      if (li < 0) continue;
      const std::size_t nb[2] = {col + 1 < w ? i + 1 : i, row + 1 < h ? i + w : i};
      const std::uint8_t bit[2] = {kContR, kContD};
      for (int t = 0; t < 2; ++t) {
        const std::size_t j = nb[t];
        const std::int32_t lj = lab_[j];
        if (j == i || lj < 0 || lj == li || !(cont_[i] & bit[t])) continue;
        border_slot(out, std::min(li, lj), std::max(li, lj));
      }
    }
  }
  const float cm = float(cos_deg(params_.merge_angle_deg));
  const float fd = float(params_.merge_dist_factor);
  auto find = [&](std::int32_t x) {
    while (parent_[std::size_t(x)] != x) {
      parent_[std::size_t(x)] = parent_[std::size_t(parent_[std::size_t(x)])];
      x = parent_[std::size_t(x)];
    }
    return x;
  };
  bool merged = false;
  for (const Border& b : out.borders) {
    const PlaneF& pa = plane_[std::size_t(b.a)];
    const PlaneF& pb = plane_[std::size_t(b.b)];
    if (pa.n.dot(pb.n) < cm) continue;
    const float range = (pa.c - viewpoint_.cast<float>()).norm();
    const float tol = fd * float(dist_abs_ + params_.dist_rel * double(range) * double(range));
    if (std::abs(pa.n.dot(pb.c - pa.c)) > tol || std::abs(pb.n.dot(pa.c - pb.c)) > tol) continue;
    const std::int32_t ra = find(b.a), rb = find(b.b);
    if (ra == rb) continue;
    const std::int32_t keep = std::min(ra, rb), gone = std::max(ra, rb);
    parent_[std::size_t(gone)] = keep;
    acc_[std::size_t(keep)].merge(acc_[std::size_t(gone)]);
    grown_[std::size_t(gone)] = 0;
    merged = true;
  }
  out.borders.clear();
  if (!merged) return;
  const std::size_t n = w * h;
  for (std::size_t i = 0; i < n; ++i) {
    if (lab_[i] >= 0) lab_[i] = find(lab_[i]);
  }
  for (std::size_t r = 0; r < R; ++r) {
    if (parent_[r] == std::int32_t(r)) refit(int(r));
  }
}

// Boundary relabelling: a cell of region A next to (depth-continuous) region B moves to B when it is closer
// to B's plane and within B's distance tolerance. Near a crease, cells of the neighbouring face lie within
// the distance tolerance of both planes; growth / edge refinement hand them to whichever region reached them
// first, which lets a face seen at a grazing angle (few cells per mm^2) take a strip of dense cells of its
// neighbours (hw-sim `default`: the cube's front face took rows of the table and of the top). Passes are
// Jacobi-style (decided on the old labels, then applied), planes stay fixed, every move strictly reduces the
// cell's plane distance, so it converges.
void Segmenter::relabel_borders(const OrganizedCloud& cloud) {
  const std::size_t w = width_, h = height_, n = w * h;
  const auto& P = cloud.points;
  if (region_count_ < 2 || params_.relabel_passes <= 0) return;
  // the cell's best other region (closer plane, within tolerance, depth-continuous), or -1
  auto better = [&](std::size_t i) -> std::int32_t {
    const std::int32_t l = lab_[i];
    std::size_t nb[4];
    std::uint8_t bit[4];
    const int k = grid_neighbours(i, w, h, nb, bit);
    const PlaneF& own = plane_[std::size_t(l)];
    float best = -1.f;
    std::int32_t bl = -1;
    for (int t = 0; t < k; ++t) {
      const std::int32_t m = lab_[nb[t]];
      if (m < 0 || m == l) continue;
      if (best < 0.f) best = std::abs(own.n.dot(P[i] - own.c));
      const PlaneF& pm = plane_[std::size_t(m)];
      const float d = std::abs(pm.n.dot(P[i] - pm.c));
      if (d < best && d <= dist_[i] && (cont_[i] & bit[t])) {
        best = d;
        bl = m;
      }
    }
    return bl;
  };
  // pass 1 looks at every cell on a region border, later passes only at the neighbours of moved cells
  std::size_t nc = 0;
  for (std::size_t row = 0, i = 0; row < h; ++row) {
    for (std::size_t col = 0; col < w; ++col, ++i) {
      const std::int32_t l = lab_[i];
      if (l < 0) continue;
      if ((col + 1 < w && lab_[i + 1] != l && lab_[i + 1] >= 0) ||
          (row + 1 < h && lab_[i + w] != l && lab_[i + w] >= 0) ||
          (col > 0 && lab_[i - 1] != l && lab_[i - 1] >= 0) ||
          (row > 0 && lab_[i - w] != l && lab_[i - w] >= 0))
        queue_[nc++] = std::uint32_t(i);
    }
  }
  for (int pass = 0; pass < params_.relabel_passes && nc > 0; ++pass) {
    std::size_t np = 0;
    for (std::size_t q = 0; q < nc; ++q) {
      const std::size_t i = queue_[q];
      state_[i] &= std::uint8_t(~kQueued);
      const std::int32_t bl = better(i);
      if (bl >= 0) {
        pend_cell_[np] = std::uint32_t(i);
        pend_label_[np] = bl;
        ++np;
      }
    }
    nc = 0;
    for (std::size_t q = 0; q < np; ++q) {
      const std::size_t i = pend_cell_[q];
      lab_[i] = pend_label_[q];
      const std::size_t row = i / w, col = i - row * w;
      const std::size_t nb[5] = {i, col > 0 ? i - 1 : i, col + 1 < w ? i + 1 : i, row > 0 ? i - w : i,
                                 row + 1 < h ? i + w : i};
      for (std::size_t j : nb) {
        if (lab_[j] < 0 || (state_[j] & kQueued)) continue;
        state_[j] |= kQueued;
        queue_[nc++] = std::uint32_t(j);
      }
    }
  }
  for (std::size_t q = 0; q < nc; ++q) state_[queue_[q]] &= std::uint8_t(~kQueued);
  (void)n;
}

void Segmenter::group_leftovers(const OrganizedCloud& /*cloud*/, Segmentation& out) {
  const std::size_t w = width_, h = height_, n = w * h;
  const std::size_t R0 = region_count_;
  // compact the grown regions: remap_[old] = new id, roots only
  std::size_t next = 0;
  for (std::size_t r = 0; r < R0; ++r) {
    remap_[r] = grown_[r] && parent_[r] == std::int32_t(r) ? std::int32_t(next++) : -1;
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (lab_[i] >= 0) lab_[i] = remap_[std::size_t(lab_[i])];
  }
  for (std::size_t r = 0; r < R0; ++r) {
    if (remap_[r] >= 0) {
      plane_[std::size_t(remap_[r])] = plane_[r];
      grown_[std::size_t(remap_[r])] = 1;
    }
  }
  region_count_ = next;
  // leftover valid cells: 4-connected, depth-continuous components become unknown regions
  for (std::size_t seed = 0; seed < n; ++seed) {
    if (lab_[seed] != kUnassigned) continue;
    if (region_count_ >= limits_.max_regions) {
      out.truncated = true;
      lab_[seed] = kNil;  // out of budget: treated like no data (supernode)
      continue;
    }
    const std::int32_t r = std::int32_t(region_count_++);
    grown_[std::size_t(r)] = 0;
    std::size_t head = 0, tail = 0;
    queue_[tail++] = std::uint32_t(seed);
    lab_[seed] = r;
    while (head < tail) {
      const std::size_t i = queue_[head++];
      std::size_t nb[4];
      std::uint8_t bit[4];
      const int k = grid_neighbours(i, w, h, nb, bit);
      for (int t = 0; t < k; ++t) {
        const std::size_t j = nb[t];
        if (lab_[j] != kUnassigned || !(cont_[i] & bit[t])) continue;
        lab_[j] = r;
        queue_[tail++] = std::uint32_t(j);
      }
    }
  }
}

void Segmenter::finalize_regions(const OrganizedCloud& cloud, Segmentation& out) {
  const std::size_t n = std::size_t(width_) * height_;
  const std::size_t R = region_count_;
  for (std::size_t r = 0; r < R; ++r) acc_[r] = Acc{};
  out.labels.resize(n);
  const auto& P = cloud.points;
  const std::size_t w = width_, h = height_;
  // Cell areas and tangent lengths from the final labels: the tangents of compute_normals() may reach across
  // a region border into a neighbouring surface (a grazing step counts as depth-continuous, up to
  // jump_max_mm), which inflates |du x dv| of every border cell. Here a tangent only uses neighbours of the
  // same region (central difference inside, one-sided at the border), so a region's area is the visible
  // surface it covers.
  auto tangent = [&](std::size_t i, std::int32_t l, bool has_prev, std::size_t prev, bool has_next,
                     std::size_t next, Eigen::Vector3f& t) {
    const bool bp = has_prev && lab_[prev] == l, bn = has_next && lab_[next] == l;
    if (bp && bn) {
      t = 0.5f * (P[next] - P[prev]);
    } else if (bn) {
      t = P[next] - P[i];
    } else if (bp) {
      t = P[i] - P[prev];
    } else {
      return false;
    }
    return true;
  };
  // Length along an axis for a cell without a same-region neighbour on it: the nearest valid neighbour's
  // distance, capped by `cap` (e.g. a one-cell-wide strip next to a jump).
  auto fallback = [&](std::size_t i, bool has_prev, std::size_t prev, bool has_next, std::size_t next,
                      float cap) {
    float d = cap;
    if (has_prev && (state_[prev] & kValid)) d = std::min(d, (P[prev] - P[i]).norm());
    if (has_next && (state_[next] & kValid)) d = std::min(d, (P[next] - P[i]).norm());
    return d;
  };
  // Area (and tangent lengths) of a cell with a neighbour outside its region or the image.
  auto border_cell_area = [&](std::size_t i, std::int32_t l, bool hl, bool hr, bool hu, bool hd) {
    Eigen::Vector3f du, dv;
    const bool tu = tangent(i, l, hl, hl ? i - 1 : i, hr, hr ? i + 1 : i, du);
    const bool tv = tangent(i, l, hu, hu ? i - w : i, hd, hd ? i + w : i, dv);
    float a = 0.f;
    if (tu && tv) {
      a = du.cross(dv).norm();
      lenu_[i] = du.squaredNorm();
      lenv_[i] = dv.squaredNorm();
    } else if (tu || tv) {
      const float len = tu ? du.norm() : dv.norm();
      const float other = tu ? fallback(i, hu, hu ? i - w : i, hd, hd ? i + w : i, std::sqrt(lenv_[i]))
                             : fallback(i, hl, hl ? i - 1 : i, hr, hr ? i + 1 : i, std::sqrt(lenu_[i]));
      a = len * other;
      lenu_[i] = tu ? len * len : other * other;
      lenv_[i] = tv ? len * len : other * other;
    } else {
      const float lu = fallback(i, hl, hl ? i - 1 : i, hr, hr ? i + 1 : i, std::sqrt(lenu_[i]));
      const float lv = fallback(i, hu, hu ? i - w : i, hd, hd ? i + w : i, std::sqrt(lenv_[i]));
      a = lu * lv;
      lenu_[i] = lu * lu;
      lenv_[i] = lv * lv;
    }
    return a;
  };
  // Moments are summed per run of equal labels along a row (in locals) and added to the region at the run's
  // end.
  const float* X = px_.data();
  const float* Y = py_.data();
  const float* Z = pz_.data();
  const std::int32_t* LB = lab_.data();
  const double ox = origin_.x(), oy = origin_.y(), oz = origin_.z();
  Acc run;
  std::int32_t run_label = -1;
  auto flush = [&]() {
    if (run_label >= 0) acc_[std::size_t(run_label)].merge(run);
    run = Acc{};
  };
  for (std::size_t row = 0, i = 0; row < h; ++row) {
    for (std::size_t col = 0; col < w; ++col, ++i) {
      const std::int32_t l = LB[i];
      out.labels[i] = l < 0 ? kNil : l;
      if (l != run_label) {
        flush();
        run_label = l;
      }
      if (l < 0) continue;
      const bool hl = col > 0, hr = col + 1 < w, hu = row > 0, hd = row + 1 < h;
      float a = 0.f;
      if (hl && hr && hu && hd && LB[i - 1] == l && LB[i + 1] == l && LB[i - w] == l && LB[i + w] == l) {
        // inside the region: central differences on both axes
        const float ux = 0.5f * (X[i + 1] - X[i - 1]), uy = 0.5f * (Y[i + 1] - Y[i - 1]),
                    uz = 0.5f * (Z[i + 1] - Z[i - 1]);
        const float vx = 0.5f * (X[i + w] - X[i - w]), vy = 0.5f * (Y[i + w] - Y[i - w]),
                    vz = 0.5f * (Z[i + w] - Z[i - w]);
        const float cx = uy * vz - uz * vy, cy = uz * vx - ux * vz, cz = ux * vy - uy * vx;
        a = std::sqrt(cx * cx + cy * cy + cz * cz);
        lenu_[i] = ux * ux + uy * uy + uz * uz;
        lenv_[i] = vx * vx + vy * vy + vz * vz;
      } else {
        a = border_cell_area(i, l, hl, hr, hu, hd);
      }
      area_[i] = a;
      const double x = double(X[i]) - ox, y = double(Y[i]) - oy, z = double(Z[i]) - oz;
      run.n += 1;
      run.sx += x;
      run.sy += y;
      run.sz += z;
      run.sxx += x * x;
      run.sxy += x * y;
      run.sxz += x * z;
      run.syy += y * y;
      run.syz += y * z;
      run.szz += z * z;
      run.area += a;
      run.pc += double(col);
      run.pr += double(row);
    }
    flush();
    run_label = -1;
  }
  out.regions.resize(R);
  for (std::size_t r = 0; r < R; ++r) {
    const Acc& a = acc_[r];
    Region& g = out.regions[r];
    g.id = std::int32_t(r);
    g.cells = std::uint32_t(a.n);
    g.area = a.area;
    Eigen::Vector3d nn, c;
    double rms = 0;
    fit(a, nn, c, rms);
    g.plane.n = nn;
    g.plane.d = nn.dot(c);
    g.centroid = c;
    g.rms = rms;
    g.pixel = Eigen::Vector2f(float(a.pc / std::max(1.0, a.n)), float(a.pr / std::max(1.0, a.n)));
    g.known = grown_[r] && g.cells >= params_.min_region_cells && g.area >= params_.min_region_area_mm2;
  }
}

void Segmenter::compute_borders(const OrganizedCloud& cloud, Segmentation& out) {
  const std::size_t w = width_, h = height_;
  clear_border_table();
  out.borders.clear();
  const auto& L = out.labels;
  std::size_t nedges = 0;
  auto add = [&](std::int32_t la, std::int32_t lb, double len, bool cont, std::uint32_t edge) {
    if (la < 0 && lb < 0) return;
    std::int32_t a, b;
    if (la >= 0 && lb >= 0) {
      a = std::min(la, lb);
      b = std::max(la, lb);
    } else {
      a = la >= 0 ? la : lb;
      b = la >= 0 ? lb : la;
    }
    const int s = border_slot(out, a, b);
    if (s < 0) return;
    Border& bd = out.borders[std::size_t(s)];
    bd.length += len;
    bd.edges += 1;
    bd.continuous += cont ? 1u : 0u;
    if (la >= 0 && lb >= 0 && edge != ~0u) {
      edge_cell_[nedges] = edge;
      edge_border_[nedges] = s;
      ++nedges;
    }
  };
  auto edge_len = [](float x2, float y2) {  // from squared tangent lengths
    const double x = std::sqrt(double(x2)), y = std::sqrt(double(y2));
    if (x > 0.0 && y > 0.0) return 0.5 * (x + y);
    return std::max(x, y);
  };
  for (std::size_t row = 0; row < h; ++row) {
    for (std::size_t col = 0; col < w; ++col) {
      const std::size_t i = row * w + col;
      const std::int32_t li = L[i];
      if (col + 1 < w && L[i + 1] != li) {
        const bool cont = li >= 0 && L[i + 1] >= 0 && (cont_[i] & kContR) != 0;
        add(li, L[i + 1], edge_len(lenv_[i], lenv_[i + 1]), cont, std::uint32_t(i * 2));
      }
      if (row + 1 < h && L[i + w] != li) {
        const bool cont = li >= 0 && L[i + w] >= 0 && (cont_[i] & kContD) != 0;
        add(li, L[i + w], edge_len(lenu_[i], lenu_[i + w]), cont, std::uint32_t(i * 2 + 1));
      }
      if (li < 0) continue;
      if (col == 0) add(li, kOutside, edge_len(lenv_[i], 0.f), false, ~0u);
      if (col + 1 == w) add(li, kOutside, edge_len(lenv_[i], 0.f), false, ~0u);
      if (row == 0) add(li, kOutside, edge_len(lenu_[i], 0.f), false, ~0u);
      if (row + 1 == h) add(li, kOutside, edge_len(lenu_[i], 0.f), false, ~0u);
    }
  }
  straight_border_lengths(cloud, out, nedges);
}

// A border between two known, non-parallel planar regions is (a piece of) a straight edge along the planes'
// intersection line. Its staircase length (sum of grid cell edges) overestimates a slanted line by up to
// sqrt(2); instead, the edge midpoints are projected onto the line and the covered extent is measured in bins
// one cell edge long (gaps of one bin are bridged, longer gaps, e.g. from occlusion, are not).
void Segmenter::straight_border_lengths(const OrganizedCloud& cloud, Segmentation& out, std::size_t nedges) {
  const std::size_t w = width_;
  const float cos_par = float(std::cos(10.0 * kPi / 180.0));
  const float inf = std::numeric_limits<float>::infinity();
  for (std::size_t k = 0; k < out.borders.size(); ++k) {
    const Border& b = out.borders[k];
    LineInfo& li = line_[k];
    li.offset = -1;
    li.count = 0;
    if (b.a < 0 || b.b < 0 || b.edges < 2) continue;
    const Region& ra = out.regions[std::size_t(b.a)];
    const Region& rb = out.regions[std::size_t(b.b)];
    if (!ra.known || !rb.known || std::abs(ra.plane.n.dot(rb.plane.n)) > double(cos_par)) continue;
    li.dir = ra.plane.n.cross(rb.plane.n).normalized().cast<float>();
    li.tmin = inf;
    li.tmax = -inf;
    li.bin = float(b.length / b.edges);
    li.count = 1;  // marks "line mode"
  }
  auto midpoint = [&](std::uint32_t e) {
    const std::size_t i = e / 2;
    const std::size_t j = (e & 1) ? i + w : i + 1;
    return Eigen::Vector3f(0.5f * (cloud.points[i] + cloud.points[j]));
  };
  for (std::size_t q = 0; q < nedges; ++q) {
    LineInfo& li = line_[std::size_t(edge_border_[q])];
    if (li.count == 0) continue;
    const float t = li.dir.dot(midpoint(edge_cell_[q]));
    li.tmin = std::min(li.tmin, t);
    li.tmax = std::max(li.tmax, t);
  }
  std::size_t used = 0;
  for (std::size_t k = 0; k < out.borders.size(); ++k) {
    LineInfo& li = line_[k];
    if (li.count == 0) continue;
    li.count = 0;
    if (!(li.bin > 0.f) || !(li.tmax >= li.tmin)) continue;
    const double nb = std::floor(double(li.tmax - li.tmin) / double(li.bin)) + 1.0;
    if (nb > double(bins_.size() - used)) continue;
    li.offset = std::int32_t(used);
    li.count = std::int32_t(nb);
    std::fill(bins_.begin() + std::ptrdiff_t(used), bins_.begin() + std::ptrdiff_t(used) + li.count, 0);
    used += std::size_t(li.count);
  }
  for (std::size_t q = 0; q < nedges; ++q) {
    const LineInfo& li = line_[std::size_t(edge_border_[q])];
    if (li.count == 0) continue;
    const float t = li.dir.dot(midpoint(edge_cell_[q]));
    const int bi = std::clamp(int((t - li.tmin) / li.bin), 0, li.count - 1);
    bins_[std::size_t(li.offset + bi)] = 1;
  }
  for (std::size_t k = 0; k < out.borders.size(); ++k) {
    const LineInfo& li = line_[k];
    if (li.count == 0) continue;
    const std::uint8_t* bn = &bins_[std::size_t(li.offset)];
    int covered = 0;
    for (int x = 0; x < li.count; ++x) {
      if (bn[x] || (x > 0 && x + 1 < li.count && bn[x - 1] && bn[x + 1])) ++covered;
    }
    Border& b = out.borders[k];
    b.length = std::min(b.length, double(covered) * double(li.bin));
  }
}

}  // namespace fs::host::seg
