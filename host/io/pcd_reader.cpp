// PCD reader (Point Cloud Library's format, v0.6/v0.7): ascii, binary and binary_compressed.
#include <lzf.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <string_view>

#include "common/error.hpp"
#include "common/formats/tokenizer.hpp"
#include "common/input_file.hpp"
#include "host/io/cloud_readers.hpp"
#include "host/io/scalar_field.hpp"

namespace fs::host {
namespace {

using HeaderLines = formats::TextLines;
using io_detail::ScalarKind;
using io_detail::ScalarType;

constexpr std::uint64_t kMaxFields = 256;
constexpr std::uint64_t kMaxCount = 1u << 16;       // elements of one field (e.g. a 308-bin descriptor)
constexpr std::uint64_t kMaxPointBytes = 1u << 20;  // one record
constexpr std::uint64_t kLzfMaxExpansion = 88;      // 3 compressed bytes -> at most 264

struct PcdField {
  std::string name;
  ScalarType type;
  std::uint32_t count = 1;
  std::uint32_t offset = 0;  // byte offset inside an interleaved record
};

enum class PcdData { Ascii, Binary, Compressed };

struct PcdHeader {
  std::vector<PcdField> fields;
  std::uint64_t width = 0, height = 0, points = 0;
  bool have_width = false, have_height = false, have_points = false, have_size = false, have_type = false;
  double viewpoint[7] = {0, 0, 0, 1, 0, 0, 0};
  PcdData data = PcdData::Ascii;
  std::uint64_t data_offset = 0;  // first byte after the DATA line
  std::uint32_t point_size = 0;
  int ix = -1, iy = -1, iz = -1, ilabel = -1;
};

PcdHeader parse_header(HeaderLines& in, const CloudReadOptions& options) {
  PcdHeader h;
  bool have_fields = false;
  bool saw_data = false;
  while (in.next()) {
    const auto& t = in.tokens();
    if (t.empty() || t[0].front() == '#') continue;
    const std::string_view key = t[0];
    if (key == "VERSION") continue;
    if (key == "FIELDS" || key == "COLUMNS") {
      if (t.size() < 2) in.fail("FIELDS: no field names");
      if (t.size() - 1 > kMaxFields) in.fail("FIELDS: more than " + std::to_string(kMaxFields) + " fields");
      h.fields.clear();
      for (std::size_t i = 1; i < t.size(); ++i) h.fields.push_back(PcdField{std::string(t[i]), {}, 1, 0});
      have_fields = true;
    } else if (key == "SIZE" || key == "TYPE" || key == "COUNT") {
      if (!have_fields) in.fail(std::string(key) + " before FIELDS");
      if (t.size() - 1 != h.fields.size())
        in.fail(std::string(key) + ": " + std::to_string(t.size() - 1) + " values for " +
                std::to_string(h.fields.size()) + " fields");
      for (std::size_t i = 0; i < h.fields.size(); ++i) {
        auto& f = h.fields[i];
        if (key == "SIZE") {
          const auto s = in.as_u64(i + 1, 8);
          if (s != 1 && s != 2 && s != 4 && s != 8)
            in.fail("SIZE of field '" + f.name + "' must be 1, 2, 4 or 8");
          f.type.size = static_cast<std::uint8_t>(s);
          h.have_size = true;
        } else if (key == "TYPE") {
          if (t[i + 1] == "F")
            f.type.kind = ScalarKind::Float;
          else if (t[i + 1] == "I")
            f.type.kind = ScalarKind::Int;
          else if (t[i + 1] == "U")
            f.type.kind = ScalarKind::UInt;
          else
            in.fail("TYPE of field '" + f.name + "' must be F, I or U, not '" + std::string(t[i + 1]) + "'");
          h.have_type = true;
        } else {
          const auto c = in.as_u64(i + 1, kMaxCount);
          if (c == 0) in.fail("COUNT of field '" + f.name + "' is 0");
          f.count = static_cast<std::uint32_t>(c);
        }
      }
    } else if (key == "WIDTH") {
      h.width = in.as_u64(1, options.max_points);
      h.have_width = true;
    } else if (key == "HEIGHT") {
      h.height = in.as_u64(1, options.max_points);
      h.have_height = true;
    } else if (key == "POINTS") {
      h.points = in.as_u64(1, options.max_points);
      h.have_points = true;
    } else if (key == "VIEWPOINT") {
      if (t.size() != 8) in.fail("VIEWPOINT needs 7 values (tx ty tz qw qx qy qz)");
      for (int i = 0; i < 7; ++i) h.viewpoint[i] = in.as_finite_double(static_cast<std::size_t>(i) + 1);
    } else if (key == "DATA") {
      if (t.size() != 2) in.fail("DATA needs one of ascii, binary, binary_compressed");
      if (t[1] == "ascii")
        h.data = PcdData::Ascii;
      else if (t[1] == "binary")
        h.data = PcdData::Binary;
      else if (t[1] == "binary_compressed")
        h.data = PcdData::Compressed;
      else
        in.fail("DATA '" + std::string(t[1]) + "' is not ascii, binary or binary_compressed");
      h.data_offset = in.offset();
      saw_data = true;
      break;
    } else {
      in.fail("unknown header keyword '" + std::string(key.substr(0, 40)) + "'");
    }
  }
  if (!saw_data)
    throw error_at_offset(in.file(), in.offset(),
                          "header ends without a DATA line (truncated or not a PCD file)");
  if (!have_fields) in.fail("no FIELDS line in the header");
  if (!h.have_size || !h.have_type) in.fail("SIZE and TYPE lines are required");
  if (!h.have_width) in.fail("no WIDTH line in the header");
  if (!h.have_height) h.height = 1;
  if (h.width == 0 || h.height == 0) in.fail("WIDTH and HEIGHT must be positive");
  if (h.width * h.height > options.max_points)
    in.fail("WIDTH x HEIGHT = " + std::to_string(h.width * h.height) + " exceeds the limit of " +
            std::to_string(options.max_points) + " points");
  if (!h.have_points) h.points = h.width * h.height;
  if (h.points != h.width * h.height)
    in.fail("POINTS " + std::to_string(h.points) +
            " != WIDTH x HEIGHT = " + std::to_string(h.width * h.height));
  std::uint64_t off = 0;
  for (std::size_t i = 0; i < h.fields.size(); ++i) {
    auto& f = h.fields[i];
    if (f.type.kind == ScalarKind::Float && f.type.size != 4 && f.type.size != 8)
      in.fail("field '" + f.name + "': float fields must have SIZE 4 or 8");
    f.offset = static_cast<std::uint32_t>(off);
    off += std::uint64_t(f.type.size) * f.count;
    if (off > kMaxPointBytes)
      in.fail("point record larger than " + std::to_string(kMaxPointBytes) + " bytes");
    const int idx = static_cast<int>(i);
    if (f.name == "x")
      h.ix = idx;
    else if (f.name == "y")
      h.iy = idx;
    else if (f.name == "z")
      h.iz = idx;
    else if (f.name == "label" && f.type.kind != ScalarKind::Float)
      h.ilabel = idx;
  }
  h.point_size = static_cast<std::uint32_t>(off);
  if (h.ix < 0 || h.iy < 0 || h.iz < 0) in.fail("FIELDS must include x, y and z");
  return h;
}

void store_point(OrganizedCloud& out, std::size_t i, double x, double y, double z) {
  if (std::isfinite(x) && std::isfinite(y) && std::isfinite(z))
    out.points[i] = Eigen::Vector3f(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
  // else: stays NaN (no data)
}

std::int32_t to_label(std::int64_t v) {
  if (v > std::numeric_limits<std::int32_t>::max() || v < std::numeric_limits<std::int32_t>::min()) return -1;
  return static_cast<std::int32_t>(v);
}

void read_ascii(std::span<const std::byte> data, const std::string& name, const PcdHeader& h,
                OrganizedCloud& out) {
  std::uint64_t values_per_point = 0;
  for (const auto& f : h.fields) values_per_point += f.count;
  std::vector<std::size_t> first(h.fields.size());
  std::size_t acc = 0;
  for (std::size_t i = 0; i < h.fields.size(); ++i) {
    first[i] = acc;
    acc += h.fields[i].count;
  }
  HeaderLines lines(data, name);
  lines.seek(h.data_offset);
  std::vector<double> vals(values_per_point);
  std::uint64_t n = 0;
  const bool labels = out.has_labels() && h.ilabel >= 0;
  while (n < h.points && lines.next(64 + values_per_point * 64)) {
    const auto& t = lines.tokens();
    if (t.empty()) continue;
    const std::uint64_t at = lines.line_offset();
    if (t.size() != values_per_point)
      throw error_at_offset(name, at,
                            "point " + std::to_string(n) + ": " + std::to_string(t.size()) +
                                " values, expected " + std::to_string(values_per_point));
    for (std::size_t k = 0; k < t.size(); ++k) {
      if (!formats::parse_double(t[k], vals[k]))
        throw error_at_offset(
            name, at,
            "point " + std::to_string(n) + ": '" + std::string(t[k].substr(0, 32)) + "' is not a number");
    }
    store_point(out, n, vals[first[h.ix]], vals[first[h.iy]], vals[first[h.iz]]);
    if (labels) {
      const double l = vals[first[h.ilabel]];
      out.labels[n] = (l == l && std::abs(l) < 2.1e9) ? static_cast<std::int32_t>(l) : -1;
    }
    ++n;
  }
  if (n < h.points)
    throw error_at_offset(
        name, data.size(),
        "truncated ascii data: " + std::to_string(n) + " of " + std::to_string(h.points) + " points");
}

// Interleaved records (binary) or one block per field (binary_compressed, after decompression).
void read_records(const std::byte* base, bool field_blocks, const PcdHeader& h, OrganizedCloud& out) {
  const auto& fx = h.fields[static_cast<std::size_t>(h.ix)];
  const auto& fy = h.fields[static_cast<std::size_t>(h.iy)];
  const auto& fz = h.fields[static_cast<std::size_t>(h.iz)];
  const bool labels = out.has_labels() && h.ilabel >= 0;
  const PcdField* fl = h.ilabel >= 0 ? &h.fields[static_cast<std::size_t>(h.ilabel)] : nullptr;
  // For field blocks, field f of point i is at points * offset_f + i * size_f * count_f.
  auto addr = [&](const PcdField& f, std::uint64_t i) {
    const std::uint64_t stride = std::uint64_t(f.type.size) * f.count;
    return field_blocks ? base + h.points * f.offset + i * stride : base + i * h.point_size + f.offset;
  };
  const bool fast = !field_blocks && fx.type.kind == ScalarKind::Float && fx.type.size == 4 &&
                    fy.type.kind == ScalarKind::Float && fy.type.size == 4 &&
                    fz.type.kind == ScalarKind::Float && fz.type.size == 4;
  for (std::uint64_t i = 0; i < h.points; ++i) {
    if (fast) {
      float x, y, z;
      const std::byte* p = base + i * h.point_size;
      std::memcpy(&x, p + fx.offset, 4);
      std::memcpy(&y, p + fy.offset, 4);
      std::memcpy(&z, p + fz.offset, 4);
      store_point(out, i, x, y, z);
    } else {
      store_point(out, i, io_detail::load_scalar(addr(fx, i), fx.type),
                  io_detail::load_scalar(addr(fy, i), fy.type), io_detail::load_scalar(addr(fz, i), fz.type));
    }
    if (labels) out.labels[i] = to_label(io_detail::load_integer(addr(*fl, i), fl->type));
  }
}

}  // namespace

void read_pcd(std::span<const std::byte> data, const std::string& name, OrganizedCloud& out,
              const CloudReadOptions& options) {
  HeaderLines in(data, name);
  const PcdHeader h = parse_header(in, options);
  const bool with_labels = options.load_labels && h.ilabel >= 0;

  const std::uint64_t payload = h.points * h.point_size;  // <= 2^26 * 2^20, no overflow
  const std::byte* records = nullptr;
  std::vector<std::byte> inflated;
  const std::uint64_t left = data.size() - h.data_offset;
  if (h.data == PcdData::Ascii) {
    // Every value takes at least 2 bytes (a digit and a separator; the last one none): a POINTS count the
    // rest of the file cannot hold is refused before the cloud is allocated.
    std::uint64_t values_per_point = 0;
    for (const auto& f : h.fields) values_per_point += f.count;
    if (h.points * values_per_point * 2 > left + 1)
      check_declared(name, "POINTS", h.points, values_per_point * 2, left,
                     "after the header (ascii: at least 2 bytes a value)");
  } else if (h.data == PcdData::Binary) {
    if (data.size() - h.data_offset < payload)
      throw error_at_offset(name, data.size(),
                            "truncated binary data: need " + std::to_string(payload) +
                                " bytes after the header at byte " + std::to_string(h.data_offset) +
                                ", file has " + std::to_string(data.size() - h.data_offset));
    records = data.data() + h.data_offset;
  } else if (h.data == PcdData::Compressed) {
    if (data.size() - h.data_offset < 8)
      throw error_at_offset(name, h.data_offset,
                            "truncated binary_compressed data: missing the 8-byte size header");
    const std::uint32_t csize = io_detail::load_as<std::uint32_t>(data.data() + h.data_offset, false);
    const std::uint32_t usize = io_detail::load_as<std::uint32_t>(data.data() + h.data_offset + 4, false);
    if (usize != payload)
      throw error_at_offset(name, h.data_offset + 4,
                            "binary_compressed: uncompressed size " + std::to_string(usize) +
                                " != POINTS x point size = " + std::to_string(payload));
    if (csize > data.size() - h.data_offset - 8)
      throw error_at_offset(name, h.data_offset,
                            "truncated binary_compressed data: compressed size " + std::to_string(csize) +
                                " but only " + std::to_string(data.size() - h.data_offset - 8) +
                                " bytes follow");
    // LZF turns 3 bytes into at most 264 (a back reference of the longest length): a larger uncompressed
    // size cannot come from csize bytes, and is refused before the buffer is allocated.
    if (payload > std::uint64_t(csize) * kLzfMaxExpansion)
      throw error_at_offset(name, h.data_offset + 4,
                            "binary_compressed: uncompressed size " + std::to_string(payload) + " (" +
                                format_bytes(payload) + ") cannot come from " + std::to_string(csize) +
                                " compressed bytes (LZF expands at most " + std::to_string(kLzfMaxExpansion) +
                                "x)");
    inflated.resize(payload);
    const unsigned got = payload == 0 ? 0
                                      : lzf_decompress(data.data() + h.data_offset + 8, csize,
                                                       inflated.data(), static_cast<unsigned>(payload));
    if (got != payload)
      throw error_at_offset(name, h.data_offset + 8,
                            "binary_compressed: corrupt LZF data (decompressed " + std::to_string(got) +
                                " of " + std::to_string(payload) + " bytes)");
    records = inflated.data();
  }

  out.reset(static_cast<std::uint32_t>(h.width), static_cast<std::uint32_t>(h.height), with_labels);
  out.viewpoint = Eigen::Vector3d(h.viewpoint[0], h.viewpoint[1], h.viewpoint[2]);
  Eigen::Quaterniond q(h.viewpoint[3], h.viewpoint[4], h.viewpoint[5], h.viewpoint[6]);
  out.viewpoint_orientation = q.norm() > 1e-12 ? q.normalized() : Eigen::Quaterniond::Identity();
  if (h.data == PcdData::Ascii)
    read_ascii(data, name, h, out);
  else
    read_records(records, h.data == PcdData::Compressed, h, out);
}

ByteBuffer read_file_bytes(const std::string& path) {
  return read_input_bytes(path, kMaxCloudFileBytes, "point-cloud file");
}

}  // namespace fs::host
