#include "host/io/cloud_writers.hpp"

#include <lzf.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>

#include <fmt/format.h>

#include "common/error.hpp"

namespace fs::host {
namespace {

template <typename T>
void put(std::string& s, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  s.append(b, sizeof(T));
}

std::string lower_ext(const std::string& path) {
  std::string e = std::filesystem::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return e;
}

}  // namespace

std::uint32_t label_colour(std::int32_t label) {
  if (label <= 0) return 0x808080;
  static constexpr std::uint32_t palette[] = {
      0xe6194b, 0x3cb44b, 0xffe119, 0x4363d8, 0xf58231, 0x911eb4, 0x46f0f0, 0xf032e6, 0xbcf60c, 0xfabebe,
      0x008080, 0xe6beff, 0x9a6324, 0xfffac8, 0x800000, 0xaaffc3, 0x808000, 0xffd8b1, 0x000075, 0xc0c0c0};
  return palette[static_cast<std::uint32_t>(label) % (sizeof(palette) / sizeof(palette[0]))];
}

std::string encode_pcd(const OrganizedCloud& cloud, PcdEncoding encoding, const CloudWriteOptions& options) {
  const bool labels = options.write_labels && cloud.has_labels();
  const bool rgb = options.colours_from_labels && cloud.has_labels();
  const std::size_t n = cloud.points.size();
  const auto& q = cloud.viewpoint_orientation;
  std::string s =
      "# .PCD v0.7 - Point Cloud Data file format (written by facetscan, millimetres)\nVERSION 0.7\n";
  s += std::string("FIELDS x y z") + (labels ? " label" : "") + (rgb ? " rgb" : "") + "\n";
  s += std::string("SIZE 4 4 4") + (labels ? " 4" : "") + (rgb ? " 4" : "") + "\n";
  s += std::string("TYPE F F F") + (labels ? " I" : "") + (rgb ? " U" : "") + "\n";
  s += std::string("COUNT 1 1 1") + (labels ? " 1" : "") + (rgb ? " 1" : "") + "\n";
  s += fmt::format("WIDTH {}\nHEIGHT {}\n", cloud.width, cloud.height);
  s += fmt::format("VIEWPOINT {} {} {} {} {} {} {}\n", cloud.viewpoint.x(), cloud.viewpoint.y(),
                   cloud.viewpoint.z(), q.w(), q.x(), q.y(), q.z());
  s += fmt::format("POINTS {}\n", n);
  auto colour = [&](std::size_t i) { return label_colour(cloud.labels[i]); };
  if (encoding == PcdEncoding::Ascii) {
    s += "DATA ascii\n";
    for (std::size_t i = 0; i < n; ++i) {
      const auto& p = cloud.points[i];
      if (OrganizedCloud::valid(p))
        s += fmt::format("{} {} {}", p.x(), p.y(), p.z());
      else
        s += "nan nan nan";
      if (labels) s += fmt::format(" {}", cloud.labels[i]);
      if (rgb) s += fmt::format(" {}", colour(i));
      s += '\n';
    }
    return s;
  }
  if (encoding == PcdEncoding::Binary) {
    s += "DATA binary\n";
    for (std::size_t i = 0; i < n; ++i) {
      const auto& p = cloud.points[i];
      put(s, p.x());
      put(s, p.y());
      put(s, p.z());
      if (labels) put(s, cloud.labels[i]);
      if (rgb) put(s, colour(i));
    }
    return s;
  }
  s += "DATA binary_compressed\n";
  std::string raw;  // one block per field
  raw.reserve(n * 20);
  for (int c = 0; c < 3; ++c)
    for (std::size_t i = 0; i < n; ++i) put(raw, cloud.points[i][c]);
  if (labels)
    for (std::size_t i = 0; i < n; ++i) put(raw, cloud.labels[i]);
  if (rgb)
    for (std::size_t i = 0; i < n; ++i) put(raw, colour(i));
  std::string packed(raw.size() + raw.size() / 16 + 64, '\0');
  unsigned csize = raw.empty() ? 0
                               : lzf_compress(raw.data(), static_cast<unsigned>(raw.size()), packed.data(),
                                              static_cast<unsigned>(packed.size()));
  if (csize == 0 && !raw.empty()) throw Error("PCD writer: LZF compression failed");
  put(s, static_cast<std::uint32_t>(csize));
  put(s, static_cast<std::uint32_t>(raw.size()));
  s.append(packed.data(), csize);
  return s;
}

std::string encode_ply(const OrganizedCloud& cloud, const CloudWriteOptions& options) {
  const bool labels = options.write_labels && cloud.has_labels();
  const bool rgb = options.colours_from_labels && cloud.has_labels();
  const bool ascii = options.ply_ascii;
  const bool grid = cloud.organized;
  std::vector<std::int32_t> vertex_of_cell;
  std::size_t nv = 0;
  vertex_of_cell.assign(cloud.points.size(), -1);
  for (std::size_t i = 0; i < cloud.points.size(); ++i)
    if (OrganizedCloud::valid(cloud.points[i])) vertex_of_cell[i] = static_cast<std::int32_t>(nv++);
  std::string s = "ply\n";
  s += ascii ? "format ascii 1.0\n" : "format binary_little_endian 1.0\n";
  s += "comment written by facetscan, millimetres\n";
  // The sensor pose (PCD's VIEWPOINT): segmentation orients normals and scales its noise model by the range
  // from it, so a cloud read back without it would segment differently.
  const auto& q = cloud.viewpoint_orientation;
  s += fmt::format("comment facetscan_viewpoint {} {} {} {} {} {} {}\n", cloud.viewpoint.x(),
                   cloud.viewpoint.y(), cloud.viewpoint.z(), q.w(), q.x(), q.y(), q.z());
  if (grid) s += fmt::format("obj_info num_cols {}\nobj_info num_rows {}\n", cloud.width, cloud.height);
  s += fmt::format("element vertex {}\nproperty float x\nproperty float y\nproperty float z\n", nv);
  if (rgb) s += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  if (labels) s += "property int label\n";
  if (grid)
    s += fmt::format("element range_grid {}\nproperty list uchar int vertex_indices\n", cloud.points.size());
  s += "end_header\n";
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    if (vertex_of_cell[i] < 0) continue;
    const auto& p = cloud.points[i];
    const std::uint32_t c = rgb ? label_colour(cloud.labels[i]) : 0;
    if (ascii) {
      s += fmt::format("{} {} {}", p.x(), p.y(), p.z());
      if (rgb) s += fmt::format(" {} {} {}", (c >> 16) & 255, (c >> 8) & 255, c & 255);
      if (labels) s += fmt::format(" {}", cloud.labels[i]);
      s += '\n';
    } else {
      put(s, p.x());
      put(s, p.y());
      put(s, p.z());
      if (rgb) {
        put(s, static_cast<std::uint8_t>((c >> 16) & 255));
        put(s, static_cast<std::uint8_t>((c >> 8) & 255));
        put(s, static_cast<std::uint8_t>(c & 255));
      }
      if (labels) put(s, cloud.labels[i]);
    }
  }
  if (grid) {
    for (std::size_t i = 0; i < cloud.points.size(); ++i) {
      const std::int32_t v = vertex_of_cell[i];
      if (ascii) {
        s += v < 0 ? "0\n" : fmt::format("1 {}\n", v);
      } else {
        put(s, static_cast<std::uint8_t>(v < 0 ? 0 : 1));
        if (v >= 0) put(s, v);
      }
    }
  }
  return s;
}

void write_cloud(const std::string& path, const OrganizedCloud& cloud, const CloudWriteOptions& options,
                 PcdEncoding pcd_encoding) {
  const std::string ext = lower_ext(path);
  std::string bytes;
  if (ext == ".pcd")
    bytes = encode_pcd(cloud, pcd_encoding, options);
  else if (ext == ".ply")
    bytes = encode_ply(cloud, options);
  else
    throw Error(path + ": unknown output format '" + ext + "' (expected .pcd or .ply)");
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) throw Error(path + ": cannot open for writing");
  f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!f) throw Error(path + ": write error");
}

}  // namespace fs::host
