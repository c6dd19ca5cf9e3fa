#pragma once
// The segmentation by cells: normals over normal_span cells and the jump threshold of jump_abs_mm (+
// jump_rel) on every grid, whatever its spacing. Tests that pin a behaviour found on scans segmented so
// (before the spans and thresholds followed the grid spacing) run them this way.
#include "host/segment/segment_params.hpp"

namespace fs::test {

inline void segment_by_cells(fs::host::seg::SegmentParams& p) {
  p.normal_span_mm = 0.0;
  p.jump_spacing_factor = 0.0;
}

}  // namespace fs::test
