#pragma once
// Readers for point-cloud files from other scanners, parsing from memory (so fuzzers and tests can feed
// bytes directly). Coordinates are stored as read (no unit conversion; load_cloud() does that).
//  * PCD v0.6/v0.7: DATA ascii | binary | binary_compressed (LZF), any FIELDS with SIZE/TYPE/COUNT, x y z
//    required, optional "label" (any integer type) -> OrganizedCloud::labels; WIDTH x HEIGHT grid; NaN in any
//    of x, y, z = no data; VIEWPOINT tx ty tz qw qx qy qz -> viewpoint / viewpoint_orientation.
//  * PLY 1.0: ascii | binary_little_endian | binary_big_endian; vertex x y z (+ optional label); organized
//    when the header gives the grid ("obj_info num_cols/num_rows", "obj_info width/height" or a PCL-style
//    "range_grid" element), else organized = false (height 1). Viewpoint from "comment facetscan_viewpoint
//    tx ty tz qw qx qy qz" (written by encode_ply) or a PCL "camera" element (view_px/py/pz); else 0.
// Malformed input throws fs::Error "<name>: at byte <offset>: <what>".
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "common/byte_buffer.hpp"
#include "host/io/organized_cloud.hpp"

namespace fs::host {

struct CloudReadOptions {
  std::uint64_t max_points = std::uint64_t(1) << 26;  // refuse larger clouds (absurd header sizes)
  bool load_labels = true;                            // copy a "label" field into OrganizedCloud::labels
};

void read_pcd(std::span<const std::byte> data, const std::string& name, OrganizedCloud& out,
              const CloudReadOptions& options = {});
void read_ply(std::span<const std::byte> data, const std::string& name, OrganizedCloud& out,
              const CloudReadOptions& options = {});

// Whole file into memory; fs::Error naming the path when it cannot be read.
ByteBuffer read_file_bytes(const std::string& path);

}  // namespace fs::host
