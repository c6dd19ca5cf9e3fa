// PLY meshes: the vertex element's scalar x, y, z and the face element's list vertex_indices (or
// vertex_index); other elements and properties are read past. Header errors and ascii body errors name the
// line, binary body errors the byte offset.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "common/formats/mesh_formats.hpp"
#include "common/formats/ply.hpp"

namespace fs::formats {
namespace {

[[noreturn]] void header_error(const std::string& src, PlyIssue issue, const TextLines& in,
                               std::string_view tok) {
  const std::uint64_t line = in.number();
  switch (issue) {
    case PlyIssue::NoMagic:
      throw error_at_line(src, 1, "not a PLY file (no 'ply' magic)");
    case PlyIssue::FormatLine:
      throw error_at_line(src, line, "expected 'format <type> 1.0'");
    case PlyIssue::UnknownFormat:
      throw error_at_line(src, line, "unknown PLY format " + quote(tok));
    case PlyIssue::ElementLine:
      throw error_at_line(src, line, "expected 'element <name> <count>'");
    case PlyIssue::BadElementCount:
      throw error_at_line(src, line, "bad element count " + quote(tok));
    case PlyIssue::PropertyBeforeElement:
      throw error_at_line(src, line, "property before any element");
    case PlyIssue::BadListCountType:
      throw error_at_line(src, line, "bad list count type " + quote(tok));
    case PlyIssue::UnknownPropertyType:
      throw error_at_line(src, line, "unknown property type " + quote(tok));
    case PlyIssue::PropertyLine:
      throw error_at_line(src, line, "expected 'property <type> <name>' or 'property list <t> <t> <name>'");
    case PlyIssue::UnknownKeyword:
      throw error_at_line(src, line, "unknown PLY header keyword " + quote(tok));
    case PlyIssue::NoEndHeader:
      throw error_at_line(src, line, "PLY header has no 'end_header'");
    case PlyIssue::NoFormat:
      throw error_at_line(src, line, "PLY header has no 'format' line");
    case PlyIssue::UnsupportedVersion:  // not enabled for meshes
    case PlyIssue::TooManyElements:
    case PlyIssue::TooManyProperties:
      break;
  }
  throw error_at_line(src, line, "bad PLY header");
}

// The body reader with the mesh reader's errors: ascii by line, binary by byte offset.
class MeshBody {
 public:
  MeshBody(std::string_view bytes, const PlyHeader& h, const std::string& src)
      : body_(bytes, h, TextStyle::Loose), body_size_(bytes.size() - h.body_offset), src_(src) {}

  double read(PlyType t) {
    double v = 0.0;
    switch (body_.read(t, v, ply_is_integer(t))) {
      case PlyBody::Status::Ok:
        return v;
      case PlyBody::Status::End:
        throw error("file ends inside the PLY data");
      case PlyBody::Status::BadNumber:
        throw error((ply_is_integer(t) ? "bad integer " : "bad number ") + quote(body_.token()));
    }
    return v;
  }
  // Error at the current position.
  Error error(const std::string& what) const {
    if (!body_.binary()) return error_at_line(src_, body_.line(), what);
    return error_at_offset(src_, body_.offset(), what);
  }
  // Ascii: the whole body's size; binary: the bytes after the cursor.
  std::size_t remaining() const { return body_.binary() ? body_.remaining() : body_size_; }
  bool binary() const { return body_.binary(); }

 private:
  PlyBody body_;
  std::size_t body_size_;
  const std::string& src_;
};

}  // namespace

Mesh parse_ply_mesh(std::string_view bytes, const std::string& src) {
  PlyHeaderRules rules;
  rules.style = TextStyle::Loose;
  rules.signed_counts = true;
  rules.fail = [&src](PlyIssue issue, const TextLines& in, std::string_view tok) {
    header_error(src, issue, in, tok);
  };
  const PlyHeader header = parse_ply_header(bytes, src, rules);

  MeshBody body(bytes, header, src);
  Mesh m;
  FaceCheck check;
  bool have_vertex = false, have_face = false;
  std::vector<std::uint32_t> face;
  for (const PlyElement& el : header.elements) {
    // Each row takes at least one byte (binary) or two (ascii: a digit and a separator) per property.
    const std::uint64_t min_row = std::max<std::size_t>(1, el.props.size()) * (body.binary() ? 1 : 2);
    if (el.count > body.remaining() / min_row + 1)
      throw body.error("element '" + el.name + "' count " + std::to_string(el.count) +
                       " exceeds what the file can hold");
    const bool is_vertex = el.name == "vertex";
    const bool is_face = el.name == "face";
    int ix = -1, iy = -1, iz = -1, iface = -1;
    for (std::size_t k = 0; k < el.props.size(); ++k) {
      const auto& p = el.props[k];
      if (is_vertex && !p.is_list && p.name == "x") ix = static_cast<int>(k);
      if (is_vertex && !p.is_list && p.name == "y") iy = static_cast<int>(k);
      if (is_vertex && !p.is_list && p.name == "z") iz = static_cast<int>(k);
      if (is_face && p.is_list && (p.name == "vertex_indices" || p.name == "vertex_index"))
        iface = static_cast<int>(k);
    }
    if (is_vertex) {
      if (ix < 0 || iy < 0 || iz < 0) throw body.error("element 'vertex' lacks scalar properties x, y, z");
      have_vertex = true;
      m.vertices.reserve(static_cast<std::size_t>(el.count));
    }
    if (is_face) {
      if (iface < 0) throw body.error("element 'face' lacks list property vertex_indices");
      have_face = true;
      m.faces.reserve(static_cast<std::size_t>(el.count));
    }
    for (std::uint64_t r = 0; r < el.count; ++r) {
      Vec3 v = Vec3::Zero();
      for (std::size_t k = 0; k < el.props.size(); ++k) {
        const auto& p = el.props[k];
        if (!p.is_list) {
          const double val = body.read(p.type);
          if (static_cast<int>(k) == ix) v.x() = val;
          if (static_cast<int>(k) == iy) v.y() = val;
          if (static_cast<int>(k) == iz) v.z() = val;
          continue;
        }
        const double cnt = body.read(p.count_type);
        if (cnt < 0 || cnt > static_cast<double>(body.remaining()))
          throw body.error("bad list length " + std::to_string(static_cast<long long>(cnt)));
        const bool keep = static_cast<int>(k) == iface;
        if (keep) face.clear();
        for (long long j = 0; j < static_cast<long long>(cnt); ++j) {
          const double val = body.read(p.type);
          if (keep) {
            if (!(val >= 0.0) || val > 4294967295.0 || val != std::floor(val))
              throw body.error("face " + std::to_string(r) + ": bad vertex index " + std::to_string(val));
            face.push_back(static_cast<std::uint32_t>(val));
          }
        }
        if (keep) {
          // Vertices normally precede faces; otherwise the index range is checked at the end.
          const std::size_t nv = have_vertex ? m.vertices.size() : std::numeric_limits<std::uint32_t>::max();
          if (auto e = check(face, nv); !e.empty()) throw body.error("face " + std::to_string(r) + ": " + e);
          m.faces.push_back(face);
        }
      }
      if (is_vertex) {
        if (auto e = check_vertex(v); !e.empty()) throw body.error("vertex " + std::to_string(r) + ": " + e);
        m.vertices.push_back(v);
      }
    }
  }
  if (!have_vertex) throw Error(src + ": PLY has no 'vertex' element");
  if (!have_face) throw Error(src + ": PLY has no 'face' element");
  for (std::size_t f = 0; f < m.faces.size(); ++f)
    if (auto e = check(m.faces[f], m.vertices.size()); !e.empty())
      throw Error(src + ": face " + std::to_string(f) + ": " + e);
  return m;
}

}  // namespace fs::formats
