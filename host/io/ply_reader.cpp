// PLY reader for point clouds: ascii and binary (little/big endian), vertex x y z (+ label), the grid from
// "obj_info num_cols/num_rows" (PCL), "obj_info width/height" or a PCL-style range_grid element; the sensor
// position from "comment facetscan_viewpoint tx ty tz qw qx qy qz" (our writer) or a PCL "camera" element
// (view_px view_py view_pz). The PLY grammar and the body decoding are common/formats/ply.hpp's.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string_view>

#include "common/error.hpp"
#include "common/formats/ply.hpp"
#include "common/input_file.hpp"
#include "host/io/cloud_readers.hpp"

namespace fs::host {
namespace {

using formats::PlyBody;
using formats::PlyElement;
using formats::PlyIssue;
using formats::PlyType;
using formats::TextLines;

constexpr std::size_t kMaxElements = 64;
constexpr std::size_t kMaxProperties = 256;

[[noreturn]] void header_error(const std::string& name, std::size_t size, PlyIssue issue, const TextLines& in,
                               std::string_view tok) {
  switch (issue) {
    case PlyIssue::NoMagic:
      throw error_at_offset(name, 0, "not a PLY file (missing 'ply' magic line)");
    case PlyIssue::FormatLine:
      in.fail("format line needs '<ascii|binary_little_endian|binary_big_endian> 1.0'");
    case PlyIssue::UnknownFormat:
      in.fail("unknown PLY format '" + std::string(tok) + "'");
    case PlyIssue::UnsupportedVersion:
      in.fail("unsupported PLY version '" + std::string(tok) + "'");
    case PlyIssue::ElementLine:
      in.fail("element line needs a name and a count");
    case PlyIssue::TooManyElements:
      in.fail("more than " + std::to_string(kMaxElements) + " elements");
    case PlyIssue::BadElementCount:
      // Every instance takes at least one byte, so a count beyond the file size is certainly wrong.
      in.as_u64(2, size);
      break;
    case PlyIssue::TooManyProperties:
      in.fail("more than " + std::to_string(kMaxProperties) + " properties");
    case PlyIssue::PropertyBeforeElement:
      in.fail("property before any element");
    case PlyIssue::BadListCountType:
      in.fail("list count type '" + std::string(tok) + "' must be an integer type");
    case PlyIssue::UnknownPropertyType:
      in.fail("unknown property type '" + std::string(tok) + "'");
    case PlyIssue::PropertyLine:
      in.fail("property line needs '<type> <name>' or 'list <count type> <type> <name>'");
    case PlyIssue::UnknownKeyword:
      in.fail("unknown header keyword '" + std::string(tok.substr(0, 40)) + "'");
    case PlyIssue::NoEndHeader:
      throw error_at_offset(name, in.offset(), "header ends without end_header (truncated?)");
    case PlyIssue::NoFormat:
      throw error_at_offset(name, 0, "no format line in the header");
  }
  in.fail("bad PLY header");
}

// The shared body reader with this reader's errors (byte offsets, the element named).
class Body {
 public:
  Body(std::string_view bytes, const formats::PlyHeader& h, const std::string& file)
      : body_(bytes, h, formats::TextStyle::Header), file_(file) {}

  double scalar(PlyType t) { return value(t); }
  std::int64_t integer(PlyType t) {
    const double v = value(t);
    if (!body_.binary()) {
      if (!(std::abs(v) < 9e15)) throw error_at_offset(file_, token_at_, "integer value out of range");
      return static_cast<std::int64_t>(v);
    }
    // Integer scalars read exactly; floats are truncated.
    if (!(v == v) || v > 9.2e18 || v < -9.2e18) return 0;
    return static_cast<std::int64_t>(v);
  }
  std::size_t pos() const { return body_.offset(); }
  std::size_t remaining() const { return body_.remaining(); }
  void set_where(std::string w) { where_ = std::move(w); }
  // At the last ascii value read (byte 0 in binary bodies).
  [[noreturn]] void fail_here(const std::string& what) const {
    throw error_at_offset(file_, token_at_, what);
  }

 private:
  double value(PlyType t) {
    double v = 0;
    const PlyBody::Status s = body_.read(t, v);
    if (body_.binary()) {
      if (s != PlyBody::Status::Ok)
        throw error_at_offset(file_, body_.offset(), "truncated data (element " + where_ + ")");
      return v;
    }
    if (s == PlyBody::Status::End)
      throw error_at_offset(file_, body_.offset(), "truncated ascii data (element " + where_ + ")");
    if (body_.token().size() > 65)
      throw error_at_offset(file_, body_.token_offset(), "ascii value longer than 64 characters");
    token_at_ = body_.token_offset();
    if (s == PlyBody::Status::BadNumber)
      throw error_at_offset(file_, body_.token_offset(),
                            "'" + std::string(body_.token()) + "' is not a number (element " + where_ + ")");
    return v;
  }

  PlyBody body_;
  const std::string& file_;
  std::size_t token_at_ = 0;
  std::string where_;
};

}  // namespace

void read_ply(std::span<const std::byte> data, const std::string& name, OrganizedCloud& out,
              const CloudReadOptions& options) {
  const std::string_view bytes(reinterpret_cast<const char*>(data.data()), data.size());
  std::uint64_t grid_w = 0, grid_h = 0;
  double viewpoint[7] = {0, 0, 0, 1, 0, 0, 0};
  bool have_viewpoint = false;
  formats::PlyHeaderRules rules;
  rules.style = formats::TextStyle::Header;
  rules.require_version_1_0 = true;
  rules.max_count = data.size();
  rules.max_elements = kMaxElements;
  rules.max_properties = kMaxProperties;
  rules.on_info = [&](const TextLines& in) {
    const auto& t = in.tokens();
    if (t[0] == "comment") {
      // Other comments are free text; ours carries the sensor pose as PCD's VIEWPOINT does.
      if (t.size() >= 2 && t[1] == "facetscan_viewpoint") {
        if (t.size() != 9) in.fail("facetscan_viewpoint needs 7 values (tx ty tz qw qx qy qz)");
        for (int i = 0; i < 7; ++i) {
          const std::string_view tok = t[static_cast<std::size_t>(i) + 2];
          if (!formats::parse_double(tok, viewpoint[i]) || !std::isfinite(viewpoint[i]))
            in.fail("facetscan_viewpoint: '" + std::string(tok.substr(0, 40)) + "' is not a finite number");
        }
        have_viewpoint = true;
      }
      return;
    }
    // obj_info: PCL writes "obj_info num_cols 640" / "obj_info num_rows 480"; also accept width/height.
    if (t.size() >= 3 && (t[1] == "num_cols" || t[1] == "width")) grid_w = in.as_u64(2, options.max_points);
    if (t.size() >= 3 && (t[1] == "num_rows" || t[1] == "height")) grid_h = in.as_u64(2, options.max_points);
  };
  rules.fail = [&](PlyIssue issue, const TextLines& in, std::string_view tok) {
    header_error(name, data.size(), issue, in, tok);
  };
  const formats::PlyHeader header = formats::parse_ply_header(bytes, name, rules);
  const std::vector<PlyElement>& elements = header.elements;

  const PlyElement* vertex = nullptr;
  int ix = -1, iy = -1, iz = -1, ilabel = -1;
  for (const auto& e : elements) {
    if (e.name != "vertex") continue;
    if (vertex) throw error_at_offset(name, header.end_offset, "more than one vertex element");
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
      else if (p.name == "label" && formats::ply_is_integer(p.type))
        ilabel = idx;
    }
  }
  if (!vertex) throw error_at_offset(name, header.end_offset, "no vertex element");
  if (ix < 0 || iy < 0 || iz < 0)
    throw error_at_offset(name, header.end_offset, "vertex element lacks x, y or z");
  if (vertex->count > options.max_points)
    throw error_at_offset(name, header.end_offset,
                          std::to_string(vertex->count) + " vertices exceed the limit of " +
                              std::to_string(options.max_points));
  // Every declared instance takes bytes of the body (ply_min_instance_bytes): counts the file cannot hold
  // are refused before anything is allocated for them.
  {
    const bool ascii = header.format == formats::PlyFormat::Ascii;
    const std::uint64_t slack = ascii ? 1 : 0;  // the last ascii value needs no separator
    std::uint64_t left = data.size() - header.body_offset;
    bool first = true;
    for (const auto& e : elements) {
      const std::uint64_t min = formats::ply_min_instance_bytes(e, header.format);
      if (min > 0 && e.count > (left + slack) / min)
        check_declared(
            name, "element '" + e.name + "'", e.count, min, left,
            std::string(first ? "after the header" : "after the header and the elements before it") +
                (ascii ? " (ascii: at least 2 bytes a value)" : ""));
      left -= std::min(left, e.count * min);
      first = false;
    }
  }
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
  Body body(bytes, header, name);
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
