// Stage 4 of the segmenter: leftover cells grouped into unknown regions, then the final regions (labels, cell
// areas, plane fits).
#include "host/segment/segmenter.hpp"

#include <algorithm>
#include <cmath>

#include "host/segment/grid_kernels.hpp"
#include "host/segment/segmenter_impl.hpp"

namespace fs::host::seg {

using namespace detail;

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
  // The row buffers hold an inner row: reserve() sized them n / 3 + 1 (a grid with one has 3 rows or more).
  const bool inner_rows = h >= 3 && w >= 3;
  float* RA = row_area_.data();
  for (std::size_t row = 0, i = 0; row < h; ++row) {
    // Cells inside a region (its label on all 4 sides): central differences on both axes, a row at a time
    // (vectorized); the others below, one by one.
    const bool inner = inner_rows && row > 0 && row + 1 < h;
    if (inner) {
      RA[0] = RA[w - 1] = -1.f;
      kernels::interior_area_row(X + i, Y + i, Z + i, LB + i, 1, int(w) - 1, std::ptrdiff_t(w), RA,
                                 row_lu_.data(), row_lv_.data());
    }
    for (std::size_t col = 0; col < w; ++col, ++i) {
      const std::int32_t l = LB[i];
      out.labels[i] = l < 0 ? kNil : l;
      if (l != run_label) {
        flush();
        run_label = l;
      }
      if (l < 0) continue;
      float a = inner ? RA[col] : -1.f;
      if (a >= 0.f) {
        lenu_[i] = row_lu_[col];
        lenv_[i] = row_lv_[col];
      } else {
        a = border_cell_area(i, l, col > 0, col + 1 < w, row > 0, row + 1 < h);
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

}  // namespace fs::host::seg
