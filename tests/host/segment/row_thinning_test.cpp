// Segmentation of every other row carried back onto every row (host/segment/row_thinning.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "host/segment/row_thinning.hpp"

namespace {

using namespace fs::host;
using namespace fs::host::seg;

// A grid of `rows` x `cols` points 1 mm apart along a row and 0.5 mm along a column, at height z(row).
template <class Z>
OrganizedCloud grid(std::uint32_t rows, std::uint32_t cols, Z z) {
  OrganizedCloud c;
  c.reset(cols, rows);
  c.viewpoint = fs::Vec3(1, 2, 300);
  for (std::uint32_t r = 0; r < rows; ++r)
    for (std::uint32_t k = 0; k < cols; ++k)
      c.at(r, k) = Eigen::Vector3f(static_cast<float>(k), 0.5f * static_cast<float>(r), z(r));
  return c;
}

Region horizontal_region(std::int32_t id, double z, bool known) {
  Region g;
  g.id = id;
  g.known = known;
  g.plane.n = fs::Vec3::UnitZ();
  g.plane.d = z;
  g.area = 100.0;
  return g;
}

TEST(RowThinning, RowStepFollowsTheSpacings) {
  EXPECT_EQ(row_step_for(0.59, 0.32), 2u);
  EXPECT_EQ(row_step_for(0.59, 0.45), 1u);
  EXPECT_EQ(row_step_for(0.59, 0.0), 1u);
  EXPECT_EQ(row_step_for(std::numeric_limits<double>::quiet_NaN(), 0.3), 1u);
}

TEST(RowThinning, ThinRowsKeepsEveryOtherRowAndTheSensor) {
  OrganizedCloud full = grid(7, 5, [](std::uint32_t r) { return static_cast<float>(r); });
  full.scanner = fs::ScannerCalibration::bench_default(7);
  OrganizedCloud thin;
  thin_rows(full, 2, thin);
  ASSERT_EQ(thin.height, 4u);
  ASSERT_EQ(thin.width, 5u);
  for (std::uint32_t r = 0; r < 4; ++r)
    for (std::uint32_t c = 0; c < 5; ++c) EXPECT_EQ(thin.at(r, c), full.at(2 * r, c)) << r << " " << c;
  EXPECT_EQ(thin.viewpoint, full.viewpoint);
  ASSERT_TRUE(thin.scanner.has_value());
  EXPECT_EQ(thin.scanner->step_count, full.scanner->step_count);
}

// Two horizontal planes: rows 0-5 at z = 10 (region 0), rows 6-11 at z = 20 (region 1); one point missing.
TEST(RowThinning, SpreadRowsLabelsEveryRowByTheNearerPlane) {
  const std::uint32_t rows = 12, cols = 4;
  OrganizedCloud full = grid(rows, cols, [](std::uint32_t r) { return r < 6 ? 10.f : 20.f; });
  const float nan = std::numeric_limits<float>::quiet_NaN();
  full.at(3, 1) = Eigen::Vector3f(nan, nan, nan);
  OrganizedCloud thin_cloud;
  thin_rows(full, 2, thin_cloud);
  Segmentation thin;
  thin.width = cols;
  thin.height = thin_cloud.height;
  thin.spacing_mm = {1.0, 1.0};
  thin.dist_mm = 0.3;
  thin.regions = {horizontal_region(0, 10.0, true), horizontal_region(1, 20.0, true)};
  thin.labels.resize(std::size_t{thin.height} * cols);
  for (std::uint32_t r = 0; r < thin.height; ++r)
    for (std::uint32_t c = 0; c < cols; ++c) thin.labels[r * cols + c] = 2 * r < 6 ? 0 : 1;
  // A cell the thinned segmentation left unlabelled (full row 2): the rows next to it take the other label.
  thin.labels[1 * cols + 2] = kNil;

  Segmentation out;
  spread_rows(full, 2, thin, out);
  ASSERT_EQ(out.width, cols);
  ASSERT_EQ(out.height, rows);
  ASSERT_EQ(out.labels.size(), std::size_t{rows} * cols);
  EXPECT_DOUBLE_EQ(out.spacing_mm.y(), 0.5);
  auto label = [&](std::uint32_t r, std::uint32_t c) { return out.labels[r * cols + c]; };
  for (std::uint32_t r = 0; r < rows; ++r)
    for (std::uint32_t c = 0; c < cols; ++c) {
      if (r == 3 && c == 1) {
        EXPECT_EQ(label(r, c), kNil);
      } else if (r == 2 && c == 2) {
        EXPECT_EQ(label(r, c), kNil) << "a kept row keeps its labels";
      } else {
        // Row 5 lies between row 4 (region 0) and row 6 (region 1): its points lie on region 0's plane. Row
        // 11 has no kept row below it.
        EXPECT_EQ(label(r, c), r < 6 ? 0 : 1) << r << " " << c;
      }
    }
  EXPECT_EQ(label(1, 2), 0) << "a row whose neighbour below has no label takes the label above";
  EXPECT_EQ(label(3, 2), 0) << "... and the other way round";
  // Cells counted on the full grid: 6 rows of region 0 less the missing point and the unlabelled kept cell.
  EXPECT_EQ(out.regions[0].cells, 6u * cols - 2u);
  EXPECT_EQ(out.regions[1].cells, 6u * cols);
  EXPECT_NEAR(out.regions[1].pixel.y(), 8.5, 1e-5);
  EXPECT_DOUBLE_EQ(out.regions[0].area, 100.0) << "areas are in mm and stay";
}

// Row 1 of three at z = 15 between a kept row of region 0 and one of region 1 (point-to-plane tolerance 0.3
// mm: a plane within 0.6 mm holds the point).
TEST(RowThinning, ACellBetweenTwoRegionsGoesToAFaceWhosePlaneHoldsIt) {
  const std::uint32_t rows = 3, cols = 2;
  OrganizedCloud full = grid(rows, cols, [](std::uint32_t) { return 15.f; });
  Segmentation thin;
  thin.width = cols;
  thin.height = 2;
  thin.dist_mm = 0.3;
  thin.labels = {0, 0, 1, 1};
  Segmentation out;
  auto middle = [&](double z0, bool known0, double z1, bool known1) {
    thin.regions = {horizontal_region(0, z0, known0), horizontal_region(1, z1, known1)};
    spread_rows(full, 2, thin, out);
    EXPECT_EQ(out.labels[1 * cols + 0], out.labels[1 * cols + 1]);
    return out.labels[1 * cols + 0];
  };
  EXPECT_EQ(middle(10.0, false, 15.5, true), 1) << "the face whose plane holds the point";
  EXPECT_EQ(middle(15.4, true, 15.2, true), 1) << "of two such faces, the nearer plane";
  EXPECT_EQ(middle(10.0, false, 30.0, true), 0) << "a face far from the point: the unknown region";
  EXPECT_EQ(middle(10.0, true, 30.0, false), 1) << "... either way round";
  EXPECT_EQ(middle(10.0, true, 16.0, true), 0)
      << "two faces far from it: the nearer row (the upper on a tie)";
  EXPECT_EQ(middle(10.0, false, 16.0, false), 0) << "two unknown regions: the same";
}

TEST(RowThinning, AFaceFewRowsReachNeedsEveryRow) {
  Segmentation thin;
  thin.spacing_mm = {1.0, 0.6};
  Region dense = horizontal_region(0, 0.0, true);
  dense.cells = 2000;
  dense.area = 1300.0;  // 0.65 mm^2 a cell
  thin.regions = {dense};
  EXPECT_FALSE(rows_sparse_somewhere(thin));
  Region sparse = horizontal_region(1, 0.0, true);
  sparse.cells = 150;
  sparse.area = 2400.0;  // 16 mm^2 a cell: rows several mm apart on it
  thin.regions.push_back(sparse);
  EXPECT_TRUE(rows_sparse_somewhere(thin));
  thin.regions[1].known = false;
  EXPECT_FALSE(rows_sparse_somewhere(thin)) << "only faces (known regions) count";
  thin.regions[1].known = true;
  thin.regions[1].area = 90.0;
  thin.regions[1].cells = 2;
  EXPECT_FALSE(rows_sparse_somewhere(thin)) << "below the least area";
}

}  // namespace
