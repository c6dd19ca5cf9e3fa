// Stage 3 of the segmenter: merge of adjacent coplanar regions, then boundary relabelling.
#include "host/segment/segmenter.hpp"

#include <algorithm>
#include <cmath>

#include "host/segment/segmenter_impl.hpp"

namespace fs::host::seg {

using namespace detail;

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

}  // namespace fs::host::seg
