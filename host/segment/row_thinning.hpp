#pragma once
// Segmentation of every k-th row, carried back onto every row. A laser sweep at fine steps gives rows that
// lie closer together than its columns (500 steps: 0.32 mm against 0.59 mm); segmenting every other row of
// such a grid finds the same faces in half the time, and every point keeps a label for what follows
// (verification, object colours, face outlines).
#include <cstdint>

#include "host/io/organized_cloud.hpp"
#include "host/segment/segmentation.hpp"

namespace fs::host::seg {

// The row step for a grid whose neighbours lie `column_mm` apart along a row and `row_mm` along a column
// (mean distances): 2 when the columns lie at least min_ratio times farther apart than the rows, else 1.
std::uint32_t row_step_for(double column_mm, double row_mm, double min_ratio = 1.5);

// Whether `thin` holds a face that few rows reach (a face turned along the stripe, seen by few image rows):
// a known region of at least min_area_mm2 whose area per cell exceeds max_cell_ratio times the grid's median
// cell (spacing x by spacing y). Such a face needs every row. A face that few columns (sweep steps) reach
// counts too, although it would not need them: the test errs toward every row.
bool rows_sparse_somewhere(const Segmentation& thin, double max_cell_ratio = 15.0,
                           double min_area_mm2 = 100.0);

// Rows 0, k, 2k, ... of `in` into `out` (reused: no allocation within its reserved capacity); viewpoint and
// scanner copied.
void thin_rows(const OrganizedCloud& in, std::uint32_t k, OrganizedCloud& out);

// `thin`, the segmentation of thin_rows(full, k), onto every row of `full` in `out` (reused). A kept row
// keeps its labels. A cell between two kept rows takes their label when they agree; when they differ, the
// label of the region whose plane lies nearer its point (a region without a plane fit, the nearer row's);
// without a point, none (kNil). Regions and borders are thin's: areas and lengths are in mm and stay; region
// cell counts and pixel centres are counted on the full grid.
void spread_rows(const OrganizedCloud& full, std::uint32_t k, const Segmentation& thin, Segmentation& out);

}  // namespace fs::host::seg
