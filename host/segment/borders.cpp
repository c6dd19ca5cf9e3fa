// Stage 5 of the segmenter: borders between regions (pair table, lengths, straight-edge lengths).
#include "host/segment/segmenter.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "host/segment/segmenter_impl.hpp"

namespace fs::host::seg {

using namespace detail;

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
