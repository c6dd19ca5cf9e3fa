#pragma once
// Segmentation of every k-th row, carried back onto every row. In a laser scan's grid a column is a sweep
// step and a row an image row along the stripe: unless the sweep is fine, the camera samples the stripe more
// densely than the sweep steps (rows about 0.32 mm apart on the bench scanner; columns 0.59 mm at 500
// steps, 1.2 mm at 250). Such a grid segmented on every other row gives the segmentation in about two thirds
// of the time (bench_recognition --segment-row-step 2, docs/performance.md), and every point keeps a label
// for what follows (verification, object colours, face outlines).
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

// `thin`, the segmentation of thin_rows(full, k), onto every row of `full` in `out` (reused; thin.width ==
// full.width, thin.height == ceil(full.height / k)). A kept row keeps its labels. A cell between two kept
// rows takes their label when they agree. When they differ, a face (known region) whose plane lies within
// twice the segmentation's point-to-plane tolerance of the cell's point takes it (the nearer plane of two);
// when neither does, an unknown region among the two, else the nearer row's label. A cell without a point
// gets none (kNil). Regions and borders are thin's: areas and lengths are in mm and stay, while a border's
// edge counts are the thinned grid's (half as many along a column). Region cell counts and pixel centres are
// counted on the full grid.
void spread_rows(const OrganizedCloud& full, std::uint32_t k, const Segmentation& thin, Segmentation& out);

}  // namespace fs::host::seg
