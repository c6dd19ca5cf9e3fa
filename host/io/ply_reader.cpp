// PLY reader for point clouds: ascii and binary (little/big endian), vertex x y z (+ label), the grid from
// "obj_info num_cols/num_rows" (PCL), "obj_info width/height" or a PCL-style range_grid element; the sensor
// position from "comment facetscan_viewpoint tx ty tz qw qx qy qz" (our writer) or a PCL "camera" element
// (view_px view_py view_pz).
#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <string_view>

#include "common/error.hpp"
#include "host/io/cloud_readers.hpp"
#include "host/io/header_lines.hpp"
#include "host/io/scalar_field.hpp"

namespace fs::host {
namespace {

using io_detail::HeaderLines;
using io_detail::ScalarKind;
using io_detail::ScalarType;

constexpr std::size_t kMaxElements = 64;
constexpr std::size_t kMaxProperties = 256;

struct PlyProperty {
  std::string name;
  ScalarType type;
  bool is_list = false;
  ScalarType count_type;
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> props;
};

enum class PlyFormat { Ascii, BinaryLE, BinaryBE };

bool parse_type(std::string_view s, ScalarType& t) {
  struct Entry {
    std::string_view a, b;
    ScalarKind k;
    std::uint8_t size;
  };
  static constexpr Entry table[] = {
      {"char", "int8", ScalarKind::Int, 1},       {"uchar", "uint8", ScalarKind::UInt, 1},
      {"short", "int16", ScalarKind::Int, 2},     {"ushort", "uint16", ScalarKind::UInt, 2},
      {"int", "int32", ScalarKind::Int, 4},       {"uint", "uint32", ScalarKind::UInt, 4},
      {"float", "float32", ScalarKind::Float, 4}, {"double", "float64", ScalarKind::Float, 8}};
  for (const auto& e : table) {
    if (s == e.a || s == e.b) {
      t = ScalarType{e.k, e.size};
      return true;
    }
  }
  return false;
}

// Sequential access to the body: binary scalars or ascii tokens, with bounds checks and byte offsets.
class Body {
 public:
  Body(std::span<const std::byte> data, std::size_t pos, PlyFormat fmt, const std::string& file)
      : data_(data),
        pos_(pos),
        fmt_(fmt),
        file_(file),
        swap_((fmt == PlyFormat::BinaryBE) == (std::endian::native == std::endian::little)) {}

  double scalar(ScalarType t) {
    if (fmt_ == PlyFormat::Ascii) return ascii_value();
    if (data_.size() - pos_ < t.size)
      throw error_at_offset(file_, pos_, "truncated data (element " + where_ + ")");
    const double v = io_detail::load_scalar(data_.data() + pos_, t, swap_);
    pos_ += t.size;
    return v;
  }
  std::int64_t integer(ScalarType t) {
    if (fmt_ == PlyFormat::Ascii) {
      const double v = ascii_value();
      if (!(std::abs(v) < 9e15)) throw error_at_offset(file_, token_at_, "integer value out of range");
      return static_cast<std::int64_t>(v);
    }
    if (data_.size() - pos_ < t.size)
      throw error_at_offset(file_, pos_, "truncated data (element " + where_ + ")");
    const std::int64_t v = io_detail::load_integer(data_.data() + pos_, t, swap_);
    pos_ += t.size;
    return v;
  }
  std::size_t pos() const { return pos_; }
  std::size_t remaining() const { return data_.size() - pos_; }
  void set_where(std::string w) { where_ = std::move(w); }
  [[noreturn]] void fail_here(const std::string& what) const {
    throw error_at_offset(file_, token_at_, what);
  }

 private:
  double ascii_value() {
    const char* base = reinterpret_cast<const char*>(data_.data());
    while (pos_ < data_.size() &&
           (base[pos_] == ' ' || base[pos_] == '\t' || base[pos_] == '\n' || base[pos_] == '\r'))
      ++pos_;
    if (pos_ >= data_.size())
      throw error_at_offset(file_, pos_, "truncated ascii data (element " + where_ + ")");
    std::size_t end = pos_;
    while (end < data_.size() && base[end] != ' ' && base[end] != '\t' && base[end] != '\n' &&
           base[end] != '\r') {
      if (end - pos_ > 64) throw error_at_offset(file_, pos_, "ascii value longer than 64 characters");
      ++end;
    }
    token_at_ = pos_;
    double v = 0;
    const std::string_view tok(base + pos_, end - pos_);
    if (!io_detail::parse_double(tok, v))
      throw error_at_offset(file_, pos_,
                            "'" + std::string(tok) + "' is not a number (element " + where_ + ")");
    pos_ = end;
    return v;
  }

  std::span<const std::byte> data_;
  std::size_t pos_;
  PlyFormat fmt_;
  const std::string& file_;
  bool swap_;
  std::size_t token_at_ = 0;
  std::string where_;
};

}  // namespace

void read_ply(std::span<const std::byte> data, const std::string& name, OrganizedCloud& out,
              const CloudReadOptions& options) {
  HeaderLines in(data, name);
  if (!in.next() || in.line() != "ply")
    throw error_at_offset(name, 0, "not a PLY file (missing 'ply' magic line)");
  PlyFormat fmt = PlyFormat::Ascii;
  bool have_format = false, have_end = false;
  std::vector<PlyElement> elements;
  std::uint64_t grid_w = 0, grid_h = 0;
  double viewpoint[7] = {0, 0, 0, 1, 0, 0, 0};
  bool have_viewpoint = false;
  while (in.next()) {
    const auto& t = in.tokens();
    if (t.empty()) continue;
    const std::string_view key = t[0];
    if (key == "comment") {
      // Other comments are free text; ours carries the sensor pose as PCD's VIEWPOINT does.
      if (t.size() >= 2 && t[1] == "facetscan_viewpoint") {
        if (t.size() != 9) in.fail("facetscan_viewpoint needs 7 values (tx ty tz qw qx qy qz)");
        for (int i = 0; i < 7; ++i) {
          const std::string_view tok = t[static_cast<std::size_t>(i) + 2];
          if (!io_detail::parse_double(tok, viewpoint[i]) || !std::isfinite(viewpoint[i]))
            in.fail("facetscan_viewpoint: '" + std::string(tok.substr(0, 40)) + "' is not a finite number");
        }
        have_viewpoint = true;
      }
      continue;
    } else if (key == "obj_info") {
      // PCL writes "obj_info num_cols 640" / "obj_info num_rows 480"; also accept width/height.
      if (t.size() >= 3 && (t[1] == "num_cols" || t[1] == "width")) grid_w = in.as_u64(2, options.max_points);
      if (t.size() >= 3 && (t[1] == "num_rows" || t[1] == "height"))
        grid_h = in.as_u64(2, options.max_points);
    } else if (key == "format") {
      if (t.size() != 3) in.fail("format line needs '<ascii|binary_little_endian|binary_big_endian> 1.0'");
      if (t[1] == "ascii")
        fmt = PlyFormat::Ascii;
      else if (t[1] == "binary_little_endian")
        fmt = PlyFormat::BinaryLE;
      else if (t[1] == "binary_big_endian")
        fmt = PlyFormat::BinaryBE;
      else
        in.fail("unknown PLY format '" + std::string(t[1]) + "'");
      if (t[2] != "1.0") in.fail("unsupported PLY version '" + std::string(t[2]) + "'");
      have_format = true;
    } else if (key == "element") {
      if (t.size() != 3) in.fail("element line needs a name and a count");
      if (elements.size() >= kMaxElements) in.fail("more than " + std::to_string(kMaxElements) + " elements");
      // Every instance takes at least one byte, so a count beyond the file size is certainly wrong.
      elements.push_back(PlyElement{std::string(t[1]), in.as_u64(2, data.size()), {}});
    } else if (key == "property") {
      if (elements.empty()) in.fail("property before any element");
      auto& props = elements.back().props;
      if (props.size() >= kMaxProperties)
        in.fail("more than " + std::to_string(kMaxProperties) + " properties");
      PlyProperty p;
      if (t.size() == 5 && t[1] == "list") {
        p.is_list = true;
        if (!parse_type(t[2], p.count_type) || p.count_type.kind == ScalarKind::Float)
          in.fail("list count type '" + std::string(t[2]) + "' must be an integer type");
        if (!parse_type(t[3], p.type)) in.fail("unknown property type '" + std::string(t[3]) + "'");
        p.name = std::string(t[4]);
      } else if (t.size() == 3) {
        if (!parse_type(t[1], p.type)) in.fail("unknown property type '" + std::string(t[1]) + "'");
        p.name = std::string(t[2]);
      } else {
        in.fail("property line needs '<type> <name>' or 'list <count type> <type> <name>'");
      }
      props.push_back(std::move(p));
    } else if (key == "end_header") {
      have_end = true;
      break;
    } else {
      in.fail("unknown header keyword '" + std::string(key.substr(0, 40)) + "'");
    }
  }
  if (!have_end) throw error_at_offset(name, in.offset(), "header ends without end_header (truncated?)");
  if (!have_format) throw error_at_offset(name, 0, "no format line in the header");

  const PlyElement* vertex = nullptr;
  int ix = -1, iy = -1, iz = -1, ilabel = -1;
  for (const auto& e : elements) {
    if (e.name != "vertex") continue;
    if (vertex) throw error_at_offset(name, in.offset(), "more than one vertex element");
    vertex = &e;
    for (std::size_t i = 0; i < e.props.size(); ++i) {
      const auto& p = e.props[i];
      const int idx = static_cast<int>(i);
      if (p.is_list) continue;
      if (p.name == "x")
        ix = idx;
      else if (p.name == "y")
        iy = idx;
      else if (p.name == "z")
        iz = idx;
      else if (p.name == "label" && p.type.kind != ScalarKind::Float)
        ilabel = idx;
    }
  }
  if (!vertex) throw error_at_offset(name, in.offset(), "no vertex element");
  if (ix < 0 || iy < 0 || iz < 0) throw error_at_offset(name, in.offset(), "vertex element lacks x, y or z");
  if (vertex->count > options.max_points)
    throw error_at_offset(name, in.offset(),
                          std::to_string(vertex->count) + " vertices exceed the limit of " +
                              std::to_string(options.max_points));
  const bool want_labels = options.load_labels && ilabel >= 0;
  // A PCL "camera" element (pcl::PLYWriter): its view_px/py/pz give the sensor origin.
  const PlyElement* camera = nullptr;
  int view_prop[3] = {-1, -1, -1};
  for (const auto& e : elements) {
    if (e.name != "camera" || e.count == 0 || camera) continue;
    int found[3] = {-1, -1, -1};
    for (std::size_t i = 0; i < e.props.size(); ++i) {
      if (e.props[i].is_list) continue;
      for (int a = 0; a < 3; ++a)
        if (e.props[i].name == std::string("view_p") + "xyz"[a]) found[a] = static_cast<int>(i);
    }
    if (found[0] >= 0 && found[1] >= 0 && found[2] >= 0) {
      camera = &e;
      std::copy(found, found + 3, view_prop);
    }
  }
  double camera_view[3] = {0, 0, 0};
  std::size_t camera_offset = 0;

  std::vector<Eigen::Vector3f> pts;
  std::vector<std::int32_t> labs;
  std::vector<std::int64_t> grid;  // range_grid cell -> vertex index or -1
  bool have_grid = false;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  Body body(data, in.offset(), fmt, name);
  std::vector<double> vals;
  for (const auto& e : elements) {
    const bool is_vertex = &e == vertex;
    const bool is_grid = e.name == "range_grid" && e.props.size() == 1 && e.props[0].is_list;
    const bool is_camera = &e == camera;
    if (is_camera) camera_offset = body.pos();
    body.set_where("'" + e.name + "'");
    if (is_vertex) {
      pts.reserve(e.count);
      if (want_labels) labs.reserve(e.count);
      vals.resize(e.props.size());
    }
    if (is_grid) {
      if (e.count > options.max_points) throw error_at_offset(name, body.pos(), "range_grid too large");
      grid.reserve(e.count);
      have_grid = true;
    }
    for (std::uint64_t n = 0; n < e.count; ++n) {
      if (body.remaining() == 0)
        throw error_at_offset(name, body.pos(),
                              "truncated data: element '" + e.name + "' " + std::to_string(n) + " of " +
                                  std::to_string(e.count));
      for (std::size_t k = 0; k < e.props.size(); ++k) {
        const auto& p = e.props[k];
        if (p.is_list) {
          const std::int64_t len = body.integer(p.count_type);
          if (len < 0 || static_cast<std::uint64_t>(len) > body.remaining())
            body.fail_here("list length " + std::to_string(len) +
                           " is negative or beyond the end of the file");
          if (is_grid) {
            if (len > 1)
              body.fail_here("range_grid cell with " + std::to_string(len) + " vertices (expected 0 or 1)");
            std::int64_t idx = -1;
            if (len == 1) {
              idx = body.integer(p.type);
              if (idx < 0 || static_cast<std::uint64_t>(idx) >= vertex->count)
                body.fail_here("range_grid vertex index " + std::to_string(idx) + " out of range");
            }
            grid.push_back(idx);
          } else {
            for (std::int64_t j = 0; j < len; ++j) body.scalar(p.type);
          }
        } else if (is_vertex) {
          if (static_cast<int>(k) == ilabel && want_labels) {
            const std::int64_t l = body.integer(p.type);
            vals[k] = 0.0;
            labs.push_back(l > std::numeric_limits<std::int32_t>::max() ||
                                   l < std::numeric_limits<std::int32_t>::min()
                               ? -1
                               : static_cast<std::int32_t>(l));
          } else {
            vals[k] = body.scalar(p.type);
          }
        } else {
          const double v = body.scalar(p.type);
          if (is_camera && n == 0)
            for (int a = 0; a < 3; ++a)
              if (view_prop[a] == static_cast<int>(k)) camera_view[a] = v;
        }
      }
      if (is_vertex) {
        const double x = vals[static_cast<std::size_t>(ix)], y = vals[static_cast<std::size_t>(iy)],
                     z = vals[static_cast<std::size_t>(iz)];
        if (std::isfinite(x) && std::isfinite(y) && std::isfinite(z))
          pts.emplace_back(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
        else
          pts.emplace_back(nan, nan, nan);
      }
    }
  }

  if (have_grid) {
    if (grid_w == 0 || grid_h == 0)
      throw error_at_offset(name, 0, "range_grid element without 'obj_info num_cols/num_rows' in the header");
    if (grid_w * grid_h != grid.size())
      throw error_at_offset(name, 0,
                            "range_grid has " + std::to_string(grid.size()) + " cells, header grid is " +
                                std::to_string(grid_w) + " x " + std::to_string(grid_h));
    out.reset(static_cast<std::uint32_t>(grid_w), static_cast<std::uint32_t>(grid_h), want_labels);
    for (std::size_t c = 0; c < grid.size(); ++c) {
      if (grid[c] < 0) continue;
      out.points[c] = pts[static_cast<std::size_t>(grid[c])];
      if (want_labels) out.labels[c] = labs[static_cast<std::size_t>(grid[c])];
    }
  } else if (grid_w > 0 && grid_h > 0) {
    if (grid_w * grid_h != pts.size())
      throw error_at_offset(name, 0,
                            "header grid " + std::to_string(grid_w) + " x " + std::to_string(grid_h) +
                                " does not match " + std::to_string(pts.size()) + " vertices");
    out.reset(static_cast<std::uint32_t>(grid_w), static_cast<std::uint32_t>(grid_h), want_labels);
    std::copy(pts.begin(), pts.end(), out.points.begin());
    if (want_labels) std::copy(labs.begin(), labs.end(), out.labels.begin());
  } else {
    out.reset(static_cast<std::uint32_t>(pts.size()), pts.empty() ? 0u : 1u, want_labels);
    std::copy(pts.begin(), pts.end(), out.points.begin());
    if (want_labels) std::copy(labs.begin(), labs.end(), out.labels.begin());
    out.organized = false;
  }
  if (camera && !have_viewpoint) {
    for (double v : camera_view)
      if (!std::isfinite(v))
        throw error_at_offset(name, camera_offset, "camera element: view point is not finite");
    viewpoint[0] = camera_view[0];
    viewpoint[1] = camera_view[1];
    viewpoint[2] = camera_view[2];
  }
  out.viewpoint = Eigen::Vector3d(viewpoint[0], viewpoint[1], viewpoint[2]);
  const Eigen::Quaterniond q(viewpoint[3], viewpoint[4], viewpoint[5], viewpoint[6]);
  out.viewpoint_orientation = q.norm() > 1e-12 ? q.normalized() : Eigen::Quaterniond::Identity();
}

}  // namespace fs::host
