#include "host/segment/segmenter.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <Eigen/Eigenvalues>

#include "common/error.hpp"

namespace fs::host::seg {
namespace {

constexpr std::int32_t kUnassigned = -3;
constexpr std::uint8_t kValid = 1, kHasNormal = 2, kSeed = 4, kTried = 8;
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

}  // namespace

void Segmenter::Acc::add(const Eigen::Vector3d& p, double a, double col, double row) {
  n += 1;
  sx += p.x(); sy += p.y(); sz += p.z();
  sxx += p.x() * p.x(); sxy += p.x() * p.y(); sxz += p.x() * p.z();
  syy += p.y() * p.y(); syz += p.y() * p.z(); szz += p.z() * p.z();
  area += a; pc += col; pr += row;
}

void Segmenter::Acc::merge(const Acc& o) {
  n += o.n; sx += o.sx; sy += o.sy; sz += o.sz;
  sxx += o.sxx; sxy += o.sxy; sxz += o.sxz; syy += o.syy; syz += o.syz; szz += o.szz;
  area += o.area; pc += o.pc; pr += o.pr;
}

Segmenter::Segmenter(const SegmentParams& params, const SegmentLimits& limits) : params_(params), limits_(limits) {
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
  if (normal_.size() >= n) return;
  normal_.resize(n);
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
  limits_.max_cells = std::max(limits_.max_cells, n);
}

void Segmenter::prepare(Segmentation& out) const {
  out.reserve(limits_.max_cells, limits_.max_regions, limits_.max_borders);
}

void Segmenter::segment(const OrganizedCloud& cloud, Segmentation& out) {
  const std::size_t n = std::size_t(cloud.width) * cloud.height;
  if (cloud.points.size() != n) {
    throw Error("segment: organized cloud has " + std::to_string(cloud.points.size()) + " points, expected width " +
                std::to_string(cloud.width) + " x height " + std::to_string(cloud.height));
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
  compute_normals(cloud);
  grow_regions(cloud, out);
  refine_edges(cloud);
  merge_regions(cloud, out);
  group_leftovers(cloud, out);
  finalize_regions(cloud, out);
  compute_borders(cloud, out);
}

void Segmenter::compute_normals(const OrganizedCloud& cloud) {
  const int w = int(width_), h = int(height_);
  const auto& P = cloud.points;
  const Eigen::Vector3f vp = viewpoint_.cast<float>();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const int span = std::max(1, params_.normal_span);
  const float jump_abs = float(params_.jump_abs_mm), jump_rel = float(params_.jump_rel);
  const float dist_abs = float(params_.dist_abs_mm), dist_rel = float(params_.dist_rel);
  // One streaming pass over the rows (the rows a step needs are still in cache): thresholds of row r, normals
  // of row r - span (its tangents need the thresholds / validity up to row r), seeds of row r - span - 1 (they
  // need the normals of the rows around them).
  // thresholds (continuity is needed by the tangents)
  auto thresholds_row = [&](int r) {
    for (int i = r * w; i < (r + 1) * w; ++i) {
      const Eigen::Vector3f& p = P[std::size_t(i)];
      if (!finite(p)) {
        state_[std::size_t(i)] = 0;
        lab_[std::size_t(i)] = kNil;
        jump2_[std::size_t(i)] = 0.f;
        dist_[std::size_t(i)] = 0.f;
        continue;
      }
      state_[std::size_t(i)] = kValid;
      lab_[std::size_t(i)] = kUnassigned;
      const float range2 = (p - vp).squaredNorm();
      const float jump = jump_abs + (jump_rel != 0.f ? jump_rel * std::sqrt(range2) : 0.f);
      jump2_[std::size_t(i)] = jump * jump;
      dist_[std::size_t(i)] = dist_abs + dist_rel * range2;
    }
  };
  // One tangent along a grid axis: central difference over +-s cells when both sides are continuous,
  // else one-sided; tries span, then 1. Returns false when no continuous neighbour exists.
  auto tangent = [&](int r, int c, int dr, int dc, Eigen::Vector3f& t) {
    const std::size_t i = std::size_t(r) * std::size_t(w) + std::size_t(c);
    const Eigen::Vector3f& p = P[i];
    for (int s = span; s >= 1; s = (s == 1 ? 0 : 1)) {
      const float lim = jump2_[i] * float(s * s);
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
      const bool fwd = r1 < h && c1 < w && (state_[std::size_t(r1) * w + c1]) && ok(P[std::size_t(r1) * w + c1]);
      const bool bwd = r0 >= 0 && c0 >= 0 && (state_[std::size_t(r0) * w + c0]) && ok(P[std::size_t(r0) * w + c0]);
      if (fwd && bwd) {
        t = (P[std::size_t(r1) * w + c1] - P[std::size_t(r0) * w + c0]) / float(2 * s);
        return true;
      }
      if (fwd) {
        t = (P[std::size_t(r1) * w + c1] - p) / float(s);
        return true;
      }
      if (bwd) {
        t = (p - P[std::size_t(r0) * w + c0]) / float(s);
        return true;
      }
      if (s == 1) break;
    }
    return false;
  };
  auto normals_row = [&](int r) {
    for (int c = 0; c < w; ++c) {
      const std::size_t i = std::size_t(r) * std::size_t(w) + std::size_t(c);
      normal_[i] = Eigen::Vector3f(nan, nan, nan);
      area_[i] = 0.f;
      lenu_[i] = 0.f;
      lenv_[i] = 0.f;
      if (!(state_[i] & kValid)) continue;
      Eigen::Vector3f du, dv;
      bool hu, hv;
      // fast path: all four neighbours at +-span valid and close (the common interior case)
      const std::size_t ws = std::size_t(w) * std::size_t(span);
      if (r >= span && r + span < h && c >= span && c + span < w && state_[i - std::size_t(span)] &&
          state_[i + std::size_t(span)] && state_[i - ws] && state_[i + ws]) {
        const float lim = jump2_[i] * float(span * span);
        const Eigen::Vector3f& p = P[i];
        const Eigen::Vector3f &pl = P[i - std::size_t(span)], &pr = P[i + std::size_t(span)], &pu = P[i - ws],
                              &pd = P[i + ws];
        if ((pl - p).squaredNorm() <= lim && (pr - p).squaredNorm() <= lim && (pu - p).squaredNorm() <= lim &&
            (pd - p).squaredNorm() <= lim) {
          const float inv = 0.5f / float(span);
          du = (pr - pl) * inv;
          dv = (pd - pu) * inv;
          hu = hv = true;
        } else {
          hu = tangent(r, c, 0, 1, du);
          hv = tangent(r, c, 1, 0, dv);
        }
      } else {
        hu = tangent(r, c, 0, 1, du);
        hv = tangent(r, c, 1, 0, dv);
      }
      if (hu) lenu_[i] = du.squaredNorm();   // squared here, sqrt where borders need it
      if (hv) lenv_[i] = dv.squaredNorm();
      if (!hu || !hv) continue;
      Eigen::Vector3f nn = du.cross(dv);
      const float a = nn.norm();
      if (!(a > 0.f)) continue;
      nn /= a;
      if (nn.dot(vp - P[i]) < 0.f) nn = -nn;
      normal_[i] = nn;
      area_[i] = a;
      state_[i] |= kHasNormal;
    }
  };
  // seeds: the normal agrees with the 4 neighbours' normals
  const float cs = float(cos_deg(params_.seed_angle_deg));
  auto seeds_row = [&](int r) {
    for (int c = 1; c + 1 < w; ++c) {
      const std::size_t i = std::size_t(r) * std::size_t(w) + std::size_t(c);
      if (!(state_[i] & kHasNormal)) continue;
      const std::size_t nb[4] = {i - 1, i + 1, i - std::size_t(w), i + std::size_t(w)};
      bool ok = true;
      for (std::size_t j : nb) {
        if (!(state_[j] & kHasNormal) || normal_[j].dot(normal_[i]) < cs || !continuous(cloud, i, j)) {
          ok = false;
          break;
        }
      }
      if (ok) state_[i] |= kSeed;
    }
  };
  for (int r = 0; r < h + span + 1; ++r) {
    if (r < h) thresholds_row(r);
    const int rn = r - span;
    if (rn >= 0 && rn < h) normals_row(rn);
    const int rs = rn - 1;
    if (rs >= 1 && rs + 1 < h) seeds_row(rs);
  }
}

Segmenter::Acc& Segmenter::acc_add_cell(int region, const OrganizedCloud& cloud, std::size_t i) {
  Acc& a = acc_[std::size_t(region)];
  const std::size_t row = i / width_;
  a.add(cloud.points[i].cast<double>() - origin_, area_[i], double(i - row * width_), double(row));
  return a;
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

void Segmenter::grow_regions(const OrganizedCloud& cloud, Segmentation& out) {
  const std::size_t w = width_, h = height_, n = w * h;
  const auto& P = cloud.points;
  const float ca = float(cos_deg(params_.angle_deg));
  const std::size_t max_grown = limits_.max_regions;
  for (std::size_t seed = 0; seed < n; ++seed) {
    if (lab_[seed] != kUnassigned || (state_[seed] & (kSeed | kTried)) != kSeed) continue;
    if (region_count_ >= max_grown) {
      out.truncated = true;
      break;
    }
    const int r = int(region_count_);
    acc_[std::size_t(r)] = Acc{};
    PlaneF& pl = plane_[std::size_t(r)];
    pl.n = normal_[seed];
    pl.c = P[seed];
    std::size_t head = 0, tail = 0;
    queue_[tail++] = std::uint32_t(seed);
    lab_[seed] = r;
    acc_add_cell(r, cloud, seed);
    double next_refit = 8;
    while (head < tail) {
      const std::size_t i = queue_[head++];
      const std::size_t row = i / w, col = i - row * w;
      std::size_t nb[4];
      int k = 0;
      if (col > 0) nb[k++] = i - 1;
      if (col + 1 < w) nb[k++] = i + 1;
      if (row > 0) nb[k++] = i - w;
      if (row + 1 < h) nb[k++] = i + w;
      for (int t = 0; t < k; ++t) {
        const std::size_t j = nb[t];
        if (lab_[j] != kUnassigned || !(state_[j] & kHasNormal)) continue;
        if (!continuous(cloud, i, j)) continue;
        if (normal_[j].dot(pl.n) < ca) continue;
        if (std::abs(pl.n.dot(P[j] - pl.c)) > dist_[j]) continue;
        lab_[j] = r;
        queue_[tail++] = std::uint32_t(j);
        const Acc& a = acc_add_cell(r, cloud, j);
        if (a.n >= next_refit) {
          refit(r);
          next_refit *= 2;
        }
      }
    }
    if (tail < params_.min_grow_cells) {
      for (std::size_t q = 0; q < tail; ++q) {
        lab_[queue_[q]] = kUnassigned;
        state_[queue_[q]] |= kTried;
      }
      continue;
    }
    refit(r);
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
      const std::size_t row = i / w, col = i - row * w;
      std::size_t nb[4];
      int k = 0;
      if (col > 0) nb[k++] = i - 1;
      if (col + 1 < w) nb[k++] = i + 1;
      if (row > 0) nb[k++] = i - w;
      if (row + 1 < h) nb[k++] = i + w;
      float best = std::numeric_limits<float>::max();
      std::int32_t bl = -1;
      for (int t = 0; t < k; ++t) {
        const std::int32_t l = lab_[nb[t]];
        if (l < 0 || !continuous(cloud, i, nb[t])) continue;
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
      acc_add_cell(pend_label_[q], cloud, pend_cell_[q]);
    }
  }
  for (std::size_t r = 0; r < region_count_; ++r) refit(int(r));
}

void Segmenter::clear_border_table() {
  std::fill(bkey_.begin(), bkey_.end(), ~std::uint64_t{0});
}

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

void Segmenter::merge_regions(const OrganizedCloud& cloud, Segmentation& out) {
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
      for (std::size_t j : nb) {
        const std::int32_t lj = lab_[j];
        if (j == i || lj < 0 || lj == li || !continuous(cloud, i, j)) continue;
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
    const float tol = fd * float(params_.dist_abs_mm + params_.dist_rel * double(range) * double(range));
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

void Segmenter::group_leftovers(const OrganizedCloud& cloud, Segmentation& out) {
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
      lab_[seed] = kNil;   // out of budget: treated like no data (supernode)
      continue;
    }
    const std::int32_t r = std::int32_t(region_count_++);
    grown_[std::size_t(r)] = 0;
    std::size_t head = 0, tail = 0;
    queue_[tail++] = std::uint32_t(seed);
    lab_[seed] = r;
    while (head < tail) {
      const std::size_t i = queue_[head++];
      const std::size_t row = i / w, col = i - row * w;
      std::size_t nb[4];
      int k = 0;
      if (col > 0) nb[k++] = i - 1;
      if (col + 1 < w) nb[k++] = i + 1;
      if (row > 0) nb[k++] = i - w;
      if (row + 1 < h) nb[k++] = i + w;
      for (int t = 0; t < k; ++t) {
        const std::size_t j = nb[t];
        if (lab_[j] != kUnassigned || !continuous(cloud, i, j)) continue;
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
  auto tangent = [&](std::size_t i, std::int32_t l, bool has_prev, std::size_t prev, bool has_next, std::size_t next,
                     Eigen::Vector3f& t) {
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
  auto fallback = [&](std::size_t i, bool has_prev, std::size_t prev, bool has_next, std::size_t next, float cap) {
    float d = cap;
    if (has_prev && (state_[prev] & kValid)) d = std::min(d, (P[prev] - P[i]).norm());
    if (has_next && (state_[next] & kValid)) d = std::min(d, (P[next] - P[i]).norm());
    return d;
  };
  for (std::size_t row = 0, i = 0; row < h; ++row) {
    for (std::size_t col = 0; col < w; ++col, ++i) {
      const std::int32_t l = lab_[i];
      out.labels[i] = l < 0 ? kNil : l;
      if (l < 0) continue;
      const bool hl = col > 0, hr = col + 1 < w, hu = row > 0, hd = row + 1 < h;
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
      area_[i] = a;
      acc_[std::size_t(l)].add(P[i].cast<double>() - origin_, a, double(col), double(row));
    }
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
  auto edge_len = [](float x2, float y2) {   // from squared tangent lengths
    const double x = std::sqrt(double(x2)), y = std::sqrt(double(y2));
    if (x > 0.0 && y > 0.0) return 0.5 * (x + y);
    return std::max(x, y);
  };
  for (std::size_t row = 0; row < h; ++row) {
    for (std::size_t col = 0; col < w; ++col) {
      const std::size_t i = row * w + col;
      const std::int32_t li = L[i];
      if (col + 1 < w && L[i + 1] != li) {
        const bool cont = li >= 0 && L[i + 1] >= 0 && continuous(cloud, i, i + 1);
        add(li, L[i + 1], edge_len(lenv_[i], lenv_[i + 1]), cont, std::uint32_t(i * 2));
      }
      if (row + 1 < h && L[i + w] != li) {
        const bool cont = li >= 0 && L[i + w] >= 0 && continuous(cloud, i, i + w);
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
    li.count = 1;   // marks "line mode"
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
