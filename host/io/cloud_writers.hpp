#pragma once
// Writers for organized clouds, so scans can be inspected in CloudCompare / MeshLab / PCL tools.
//  * PCD v0.7: FIELDS x y z [label] [rgb], WIDTH x HEIGHT, NaN points kept (organized), DATA ascii | binary |
//    binary_compressed (LZF).
//  * PLY 1.0 (binary little endian or ascii): the valid points as vertices (x y z float [red green blue
//  uchar]
//    [label int]); organized clouds also get "obj_info num_cols/num_rows" and a PCL-style range_grid element
//    (one list of 0 or 1 vertex index per grid cell, row-major), which read_ply() turns back into the grid;
//    the viewpoint as "comment facetscan_viewpoint tx ty tz qw qx qy qz" (PCD's VIEWPOINT), read back too.
// Colours: labels <= 0 grey, others a fixed palette colour per label.
#include <cstdint>
#include <string>

#include "host/io/organized_cloud.hpp"

namespace fs::host {

enum class PcdEncoding { Ascii, Binary, BinaryCompressed };

struct CloudWriteOptions {
  bool write_labels = true;          // a "label" field when the cloud has labels
  bool colours_from_labels = false;  // an rgb colour per point from its label
  bool ply_ascii = false;            // PLY: ascii instead of binary_little_endian
};

std::string encode_pcd(const OrganizedCloud& cloud, PcdEncoding encoding,
                       const CloudWriteOptions& options = {});
std::string encode_ply(const OrganizedCloud& cloud, const CloudWriteOptions& options = {});
// By extension (.pcd -> binary_compressed unless encoding given, .ply); throws fs::Error on I/O failure.
void write_cloud(const std::string& path, const OrganizedCloud& cloud, const CloudWriteOptions& options = {},
                 PcdEncoding pcd_encoding = PcdEncoding::BinaryCompressed);

// The palette colour of a label, 0xRRGGBB.
std::uint32_t label_colour(std::int32_t label);

}  // namespace fs::host
