// Stage 1 of the segmenter: depth-noise estimate, then per-cell normals, depth-continuity bits and seeds.
#include "host/segment/segmenter.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "host/segment/grid_kernels.hpp"
#include "host/segment/segmenter_impl.hpp"

namespace fs::host::seg {

using namespace detail;

// Medians over a subsample of the cells whose right / lower neighbour has data: depth jumps are a small
// share of the neighbour pairs, so they do not move the median (a mean would need a cap).
Eigen::Vector2d Segmenter::estimate_spacing(const OrganizedCloud& cloud) {
  const std::uint32_t w = cloud.width, h = cloud.height;
  Eigen::Vector2d out = Eigen::Vector2d::Zero();
  if (w < 2 || h < 2) return out;
  const std::size_t half = kSamples / 2;
  const std::uint32_t stride = std::max<std::uint32_t>(
      1, static_cast<std::uint32_t>((std::size_t(w - 1) * (h - 1) + half - 1) / half));
  for (int axis = 0; axis < 2; ++axis) {
    samples_.clear();
    const std::size_t step = axis == 0 ? 1 : w;
    for (std::size_t k = 0; k < std::size_t(w - 1) * (h - 1) && samples_.size() < half; k += stride) {
      const std::size_t i = (k / (w - 1)) * w + k % (w - 1);
      const Eigen::Vector3f& p = cloud.points[i];
      const Eigen::Vector3f& q = cloud.points[i + step];
      if (finite(p) && finite(q)) samples_.push_back((q - p).norm());
    }
    if (samples_.size() < 64) continue;
    auto mid = samples_.begin() + static_cast<std::ptrdiff_t>(samples_.size() / 2);
    std::nth_element(samples_.begin(), mid, samples_.end());
    out[axis] = double(*mid);
  }
  return out;
}

// The component of p[c-1] - 2 p[c] + p[c+1] across the local tangent p[c+1] - p[c-1]: 0 on a plane (the three
// points lie on the line where the row meets the surface, whatever their spacing), noise of variance ~6
// sigma^2 otherwise. The median over a subsample of depth-continuous triples ignores creases and edges.
double Segmenter::estimate_noise(const OrganizedCloud& cloud) {
  samples_.clear();
  const std::uint32_t w = cloud.width, h = cloud.height;
  if (w < 3 || h == 0) return 0.0;
  const std::size_t per_row = w - 2;
  const std::uint32_t stride =
      std::max<std::uint32_t>(1, static_cast<std::uint32_t>((per_row * h + kSamples - 1) / kSamples));
  const float jump2 = std::max(float(params_.jump_abs_mm * params_.jump_abs_mm), floor2_x_);
  for (std::uint32_t r = 0; r < h; r += stride) {
    const Eigen::Vector3f* row = cloud.points.data() + std::size_t(r) * w;
    for (std::uint32_t c = 1; c + 1 < w && samples_.size() < kSamples; ++c) {
      const Eigen::Vector3f& a = row[c - 1];
      const Eigen::Vector3f& b = row[c];
      const Eigen::Vector3f& d = row[c + 1];
      if (!finite(a) || !finite(b) || !finite(d)) continue;
      const Eigen::Vector3f t = d - a;
      const float tt = t.squaredNorm();
      if (!(tt > 0.0f) || (b - a).squaredNorm() > jump2 || (d - b).squaredNorm() > jump2) continue;
      const Eigen::Vector3f d2 = a - 2.0f * b + d;
      samples_.push_back((d2 - (d2.dot(t) / tt) * t).norm());
    }
  }
  if (samples_.size() < 64) return 0.0;
  auto mid = samples_.begin() + static_cast<std::ptrdiff_t>(samples_.size() / 2);
  std::nth_element(samples_.begin(), mid, samples_.end());
  // |N(0, 6 s^2)| has median 0.6745 sqrt(6) s.
  return double(*mid) / (0.6745 * std::sqrt(6.0));
}

void Segmenter::compute_normals(const OrganizedCloud& cloud) {
  using namespace kernels;
  const int w = int(width_), h = int(height_);
  if (w == 0 || h == 0) return;
  const std::size_t W = std::size_t(w);
  const std::ptrdiff_t sW = std::ptrdiff_t(W);  // row offsets for the kernels (signed: rows above)
  const auto& P = cloud.points;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const int sx = span_x_, sy = span_y_;
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
  // thresholds of row r, normals of row r - sy (its tangents need rows up to r), continuity bits and seeds
  // of row r - sy - 1 (they need the normals of the rows around them). The common interior cases run in the
  // vectorized kernels of grid_kernels.hpp; the rest (image border, missing data, depth jumps) takes the
  // scalar path with one-sided tangents.
  auto thresholds_row = [&](int r) {
    const std::size_t b = std::size_t(r) * W;
    soa_row(P[b].data(), w, vpk, float(params_.jump_abs_mm), float(params_.jump_rel), float(dist_abs_),
            float(params_.dist_rel), X + b, Y + b, Z + b, J2 + b, dist_.data() + b, ST + b);
    for (std::size_t i = b; i < b + W; ++i) lab_[i] = ST[i] ? kUnassigned : kNil;  // ST: 1 = kValid or 0
  };
  // One tangent along a grid axis: central difference over +-s cells when both sides are continuous,
  // else one-sided; tries the axis's span (sx, sy), then 1. Returns false when no continuous neighbour
  // exists.
  auto tangent = [&](int r, int c, int dr, int dc, Eigen::Vector3f& t) {
    const std::size_t i = std::size_t(r) * W + std::size_t(c);
    const Eigen::Vector3f& p = P[i];
    for (int s = dc != 0 ? sx : sy; s >= 1; s = (s == 1 ? 0 : 1)) {
      const float lim = std::max(J2[i], dc != 0 ? floor2_x_ : floor2_y_) * float(s * s);
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
    const bool inner_row = r >= sy && r + sy < h && w > 2 * sx;
    const int c0 = inner_row ? sx : 0, c1 = inner_row ? w - sx : 0;
    if (inner_row) {
      normals_row_fast(X + b, Y + b, Z + b, J2 + b, floor2_x_, floor2_y_, c0, c1, sx, sy, sW, vpk, NX + b,
                       NY + b, NZ + b, AR + b, LU + b, LV + b);
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
      cont_seeds_row_fast(X + b, Y + b, Z + b, J2 + b, floor2_x_, floor2_y_, NX + b, NY + b, NZ + b, c0, c1,
                          sW, vpk, jump_max2_, cos2_jump_, cs, CT + b);
    }
    for (int c = 0; c < w; ++c) {
      const std::ptrdiff_t i = std::ptrdiff_t(b) + c;
      if (c >= c0 && c < c1) {
        ST[i] |= (CT[i] & kContSeed) ? kSeed : 0;
        CT[i] &= std::uint8_t(~kContSeed);
        continue;
      }
      std::uint8_t bits = 0;
      const float jx = std::max(J2[i], floor2_x_), jy = std::max(J2[i], floor2_y_);
      if (c > 0 && kernels::continuous(X, Y, Z, jx, i, i - 1, vpk, jump_max2_, cos2_jump_)) bits |= kContL;
      if (c + 1 < w && kernels::continuous(X, Y, Z, jx, i, i + 1, vpk, jump_max2_, cos2_jump_))
        bits |= kContR;
      if (r > 0 && kernels::continuous(X, Y, Z, jy, i, i - sW, vpk, jump_max2_, cos2_jump_)) bits |= kContU;
      if (r + 1 < h && kernels::continuous(X, Y, Z, jy, i, i + sW, vpk, jump_max2_, cos2_jump_))
        bits |= kContD;
      CT[i] = bits;
    }
  };
  for (int r = 0; r < h + sy + 1; ++r) {
    if (r < h) thresholds_row(r);
    const int rn = r - sy;
    if (rn >= 0 && rn < h) normals_row(rn);
    const int rs = rn - 1;
    if (rs >= 0 && rs < h) seeds_row(rs);
  }
}

}  // namespace fs::host::seg
