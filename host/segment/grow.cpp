// Stage 2 of the segmenter: region growing from seeds (breadth-first start, scanline flood fill), then edge
// refinement of the cells left between regions.
#include "host/segment/segmenter.hpp"

#include <cmath>
#include <limits>

#include "host/segment/segmenter_impl.hpp"

namespace fs::host::seg {

using namespace detail;

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

}  // namespace fs::host::seg
