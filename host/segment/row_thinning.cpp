#include "host/segment/row_thinning.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace fs::host::seg {

std::uint32_t row_step_for(double column_mm, double row_mm, double min_ratio) {
  if (!(row_mm > 0.0) || !(column_mm > 0.0)) return 1;
  return column_mm >= min_ratio * row_mm ? 2 : 1;
}

bool rows_sparse_somewhere(const Segmentation& thin, double max_cell_ratio, double min_area_mm2) {
  const double cell = thin.spacing_mm.x() * thin.spacing_mm.y();
  if (!(cell > 0.0)) return true;
  for (const Region& g : thin.regions)
    if (g.known && g.area >= min_area_mm2 && g.area > max_cell_ratio * cell * static_cast<double>(g.cells))
      return true;
  return false;
}

void thin_rows(const OrganizedCloud& in, std::uint32_t k, OrganizedCloud& out) {
  k = std::max<std::uint32_t>(1, k);
  const std::uint32_t rows = (in.height + k - 1) / k;
  out.width = in.width;
  out.height = rows;
  out.organized = in.organized;
  out.viewpoint = in.viewpoint;
  out.viewpoint_orientation = in.viewpoint_orientation;
  out.scanner = in.scanner;
  out.labels.clear();
  out.points.resize(static_cast<std::size_t>(rows) * in.width);
  for (std::uint32_t r = 0; r < rows; ++r) {
    const auto src = in.points.begin() + static_cast<std::ptrdiff_t>(std::size_t{r} * k * in.width);
    std::copy(src, src + in.width,
              out.points.begin() + static_cast<std::ptrdiff_t>(std::size_t{r} * in.width));
  }
}

namespace {

// A point lies on a region's face when within this many times the segmentation's point-to-plane tolerance
// (Segmentation::dist_mm) of its plane.
constexpr double kOnPlane = 2.0;

}  // namespace

void spread_rows(const OrganizedCloud& full, std::uint32_t k, const Segmentation& thin, Segmentation& out) {
  k = std::max<std::uint32_t>(1, k);
  const std::uint32_t w = full.width, h = full.height;
  out.width = w;
  out.height = h;
  out.truncated = thin.truncated;
  out.noise_mm = thin.noise_mm;
  out.dist_mm = thin.dist_mm;
  out.spacing_mm = {thin.spacing_mm.x(), thin.spacing_mm.y() / static_cast<double>(k)};
  out.regions.assign(thin.regions.begin(), thin.regions.end());
  out.borders.assign(thin.borders.begin(), thin.borders.end());
  out.labels.resize(static_cast<std::size_t>(w) * h);
  const std::uint32_t thin_rows_n = thin.height;
  const double tol = kOnPlane * thin.dist_mm;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  auto thin_label = [&](std::uint32_t tr, std::uint32_t c) {
    return tr < thin_rows_n ? thin.labels[std::size_t{tr} * w + c] : kNil;
  };
  for (std::uint32_t r = 0; r < h; ++r) {
    const std::uint32_t tr = r / k, j = r % k;
    std::int32_t* row = out.labels.data() + std::size_t{r} * w;
    if (j == 0) {
      std::copy_n(thin.labels.data() + std::size_t{tr} * w, w, row);
      continue;
    }
    const bool upper_nearer = 2 * j <= k;
    for (std::uint32_t c = 0; c < w; ++c) {
      const Eigen::Vector3f& p = full.points[std::size_t{r} * w + c];
      if (!OrganizedCloud::valid(p)) {
        row[c] = kNil;
        continue;
      }
      const std::int32_t a = thin_label(tr, c), b = thin_label(tr + 1, c);
      if (a == b || b < 0) {
        row[c] = a >= 0 ? a : b;
        continue;
      }
      if (a < 0) {
        row[c] = b;
        continue;
      }
      // Two labels: a face whose plane holds the point (the nearer plane of two); neither, what fits no plane
      // (an unknown region) of the two, else the nearer row's.
      const Region& ga = thin.regions[static_cast<std::size_t>(a)];
      const Region& gb = thin.regions[static_cast<std::size_t>(b)];
      const Vec3 q = p.cast<double>();
      const double da = ga.known ? std::abs(ga.plane.signed_distance(q)) : kInf;
      const double db = gb.known ? std::abs(gb.plane.signed_distance(q)) : kInf;
      if (da <= tol || db <= tol)
        row[c] = da < db ? a : db < da ? b : (upper_nearer ? a : b);
      else if (ga.known != gb.known)
        row[c] = ga.known ? b : a;
      else
        row[c] = upper_nearer ? a : b;
    }
  }
  // Cell counts and pixel centres on the full grid.
  for (Region& g : out.regions) {
    g.cells = 0;
    g.pixel.setZero();
  }
  for (std::uint32_t r = 0; r < h; ++r) {
    const std::int32_t* row = out.labels.data() + std::size_t{r} * w;
    for (std::uint32_t c = 0; c < w; ++c) {
      if (row[c] < 0) continue;
      Region& g = out.regions[static_cast<std::size_t>(row[c])];
      ++g.cells;
      g.pixel += Eigen::Vector2f(static_cast<float>(c), static_cast<float>(r));
    }
  }
  for (Region& g : out.regions)
    if (g.cells > 0) g.pixel /= static_cast<float>(g.cells);
}

}  // namespace fs::host::seg
