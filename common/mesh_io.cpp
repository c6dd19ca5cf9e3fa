#include "common/mesh_io.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <optional>
#include <unordered_map>

#include "common/error.hpp"

namespace fs {
namespace {

// ---------------------------------------------------------------------------------------------------------
// Text helpers

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string quote(std::string_view tok) {
  std::string t(tok.substr(0, 40));
  for (char& c : t)
    if (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126) c = '?';
  return "'" + t + (tok.size() > 40 ? "...'" : "'");
}

std::optional<double> to_double(std::string_view tok) {
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  if (tok.empty()) return std::nullopt;
  double v = 0.0;
  const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), v);
  if (r.ec != std::errc() || r.ptr != tok.data() + tok.size()) return std::nullopt;
  return v;
}

std::optional<long long> to_int(std::string_view tok) {
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  if (tok.empty()) return std::nullopt;
  long long v = 0;
  const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), v);
  if (r.ec != std::errc() || r.ptr != tok.data() + tok.size()) return std::nullopt;
  return v;
}

// Splits a string into lines (LF or CRLF), numbered from 1.
class Lines {
 public:
  explicit Lines(std::string_view text) : text_(text) {}
  bool next(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    const std::size_t end = text_.find('\n', pos_);
    const std::size_t stop = end == std::string_view::npos ? text_.size() : end;
    line = text_.substr(pos_, stop - pos_);
    pos_ = stop == text_.size() ? stop : stop + 1;
    ++number_;
    return true;
  }
  std::uint64_t number() const { return number_; }
  std::size_t position() const { return pos_; }

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
  std::uint64_t number_ = 0;
};

// Whitespace-separated tokens of one line; `comment` starts a comment to the end of the line.
std::size_t split(std::string_view line, std::vector<std::string_view>& out, char comment) {
  out.clear();
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_space(line[i])) ++i;
    if (i >= line.size() || (comment != 0 && line[i] == comment)) break;
    const std::size_t start = i;
    while (i < line.size() && !is_space(line[i]) && !(comment != 0 && line[i] == comment)) ++i;
    out.push_back(line.substr(start, i - start));
  }
  return out.size();
}

// Token stream over a whole text with line numbers (for ASCII STL and ASCII PLY bodies).
class Tokens {
 public:
  Tokens(std::string_view text, std::uint64_t first_line) : text_(text), line_(first_line) {}
  bool next(std::string_view& tok) {
    while (pos_ < text_.size() && (is_space(text_[pos_]) || text_[pos_] == '\n')) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
    if (pos_ >= text_.size()) return false;
    const std::size_t start = pos_;
    while (pos_ < text_.size() && !is_space(text_[pos_]) && text_[pos_] != '\n') ++pos_;
    tok = text_.substr(start, pos_ - start);
    return true;
  }
  std::uint64_t line() const { return line_; }

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
  std::uint64_t line_;
};

// ---------------------------------------------------------------------------------------------------------
// Shared validation

struct FaceCheck {
  std::vector<std::uint32_t> sorted;
  // Returns "" or what is wrong with the face.
  std::string operator()(const std::vector<std::uint32_t>& face, std::size_t vertex_count) {
    if (face.size() < 3) return "face has " + std::to_string(face.size()) + " vertices (need at least 3)";
    for (std::uint32_t i : face)
      if (i >= vertex_count)
        return "vertex index " + std::to_string(i) + " out of range (" + std::to_string(vertex_count) +
               " vertices)";
    sorted.assign(face.begin(), face.end());
    std::sort(sorted.begin(), sorted.end());
    const auto dup = std::adjacent_find(sorted.begin(), sorted.end());
    if (dup != sorted.end()) return "face repeats vertex " + std::to_string(*dup);
    return {};
  }
};

std::string check_vertex(const Vec3& v) {
  if (!std::isfinite(v.x()) || !std::isfinite(v.y()) || !std::isfinite(v.z())) return "non-finite coordinate";
  return {};
}

void check_not_empty(const Mesh& m, const std::string& source) {
  if (m.vertices.empty()) throw Error(source + ": mesh has no vertices");
  if (m.faces.empty()) throw Error(source + ": mesh has no faces");
}

// ---------------------------------------------------------------------------------------------------------
// OFF: [C|N|ST...]OFF header, "nv nf ne", nv vertex lines (x y z [extra]), nf face lines (n i1..in [colour]).

Mesh parse_off(std::string_view text, const std::string& src) {
  Mesh m;
  Lines lines(text);
  std::vector<std::string_view> tok;
  std::string_view line;
  auto next_content = [&]() -> bool {
    while (lines.next(line))
      if (split(line, tok, '#') > 0) return true;
    return false;
  };
  if (!next_content()) throw Error(src + ": empty OFF file");
  std::size_t first = 0;
  const std::string head = lower(tok[0]);
  if (head.size() >= 3 && head.compare(head.size() - 3, 3, "off") == 0) {
    if (head != "off" && head != "coff" && head != "noff" && head != "cnoff" && head != "stoff" &&
        head != "stcoff")
      throw error_at_line(src, lines.number(), "unsupported OFF variant " + quote(tok[0]));
    first = 1;
    if (tok.size() == 1) {
      if (!next_content()) throw error_at_line(src, lines.number(), "missing OFF counts");
      first = 0;
    }
  }
  if (tok.size() < first + 2)
    throw error_at_line(src, lines.number(), "expected 'vertex_count face_count [edge_count]'");
  const auto nv = to_int(tok[first]);
  const auto nf = to_int(tok[first + 1]);
  if (!nv || *nv < 0) throw error_at_line(src, lines.number(), "bad vertex count " + quote(tok[first]));
  if (!nf || *nf < 0) throw error_at_line(src, lines.number(), "bad face count " + quote(tok[first + 1]));
  if (*nv == 0) throw error_at_line(src, lines.number(), "mesh has no vertices (vertex count 0)");
  if (*nf == 0) throw error_at_line(src, lines.number(), "mesh has no faces (face count 0)");
  // Each vertex needs >= 6 bytes ("0 0 0\n"), each face >= 8: counts beyond that cannot be in the file.
  const auto remaining = static_cast<long long>(text.size() - lines.position());
  if (*nv > remaining / 6 + 1)
    throw error_at_line(src, lines.number(),
                        "vertex count " + std::to_string(*nv) + " exceeds what the file can hold");
  if (*nf > remaining / 8 + 1)
    throw error_at_line(src, lines.number(),
                        "face count " + std::to_string(*nf) + " exceeds what the file can hold");
  m.vertices.reserve(static_cast<std::size_t>(*nv));
  m.faces.reserve(static_cast<std::size_t>(*nf));
  for (long long i = 0; i < *nv; ++i) {
    if (!next_content())
      throw error_at_line(
          src, lines.number(),
          "file ends after " + std::to_string(i) + " of " + std::to_string(*nv) + " vertices");
    if (tok.size() < 3)
      throw error_at_line(src, lines.number(), "vertex " + std::to_string(i) + " needs 3 coordinates");
    Vec3 v;
    for (int k = 0; k < 3; ++k) {
      const auto d = to_double(tok[static_cast<std::size_t>(k)]);
      if (!d)
        throw error_at_line(src, lines.number(), "bad coordinate " + quote(tok[static_cast<std::size_t>(k)]));
      v[k] = *d;
    }
    if (auto e = check_vertex(v); !e.empty())
      throw error_at_line(src, lines.number(), "vertex " + std::to_string(i) + ": " + e);
    m.vertices.push_back(v);
  }
  FaceCheck check;
  for (long long f = 0; f < *nf; ++f) {
    if (!next_content())
      throw error_at_line(src, lines.number(),
                          "file ends after " + std::to_string(f) + " of " + std::to_string(*nf) + " faces");
    const auto n = to_int(tok[0]);
    if (!n || *n < 0) throw error_at_line(src, lines.number(), "bad face vertex count " + quote(tok[0]));
    if (static_cast<long long>(tok.size()) - 1 < *n)
      throw error_at_line(src, lines.number(),
                          "face " + std::to_string(f) + " declares " + std::to_string(*n) +
                              " vertices but lists " + std::to_string(tok.size() - 1));
    std::vector<std::uint32_t> face;
    face.reserve(static_cast<std::size_t>(*n));
    for (long long k = 1; k <= *n; ++k) {
      const auto idx = to_int(tok[static_cast<std::size_t>(k)]);
      if (!idx)
        throw error_at_line(src, lines.number(),
                            "bad vertex index " + quote(tok[static_cast<std::size_t>(k)]));
      if (*idx < 0 || *idx >= *nv)
        throw error_at_line(
            src, lines.number(),
            "vertex index " + std::to_string(*idx) + " out of range (" + std::to_string(*nv) + " vertices)");
      face.push_back(static_cast<std::uint32_t>(*idx));
    }
    if (auto e = check(face, m.vertices.size()); !e.empty())
      throw error_at_line(src, lines.number(), "face " + std::to_string(f) + ": " + e);
    m.faces.push_back(std::move(face));
  }
  return m;
}

// ---------------------------------------------------------------------------------------------------------
// OBJ: "v x y z [w]" and "f a a/b a//c a/b/c ..." (1-based, negative = relative); everything else ignored.

Mesh parse_obj(std::string_view text, const std::string& src) {
  Mesh m;
  Lines lines(text);
  std::vector<std::string_view> tok;
  std::string_view line;
  FaceCheck check;
  std::vector<std::uint64_t> face_lines;
  long long max_index_seen = 0;
  std::uint64_t max_index_line = 0;
  while (lines.next(line)) {
    if (split(line, tok, '#') == 0) continue;
    if (tok[0] == "v") {
      if (tok.size() < 4) throw error_at_line(src, lines.number(), "vertex needs 3 coordinates");
      Vec3 v;
      for (int k = 0; k < 3; ++k) {
        const auto d = to_double(tok[static_cast<std::size_t>(k + 1)]);
        if (!d)
          throw error_at_line(src, lines.number(),
                              "bad coordinate " + quote(tok[static_cast<std::size_t>(k + 1)]));
        v[k] = *d;
      }
      if (auto e = check_vertex(v); !e.empty())
        throw error_at_line(src, lines.number(), "vertex " + std::to_string(m.vertices.size()) + ": " + e);
      m.vertices.push_back(v);
    } else if (tok[0] == "f") {
      std::vector<std::uint32_t> face;
      for (std::size_t k = 1; k < tok.size(); ++k) {
        const std::string_view t = tok[k].substr(0, tok[k].find('/'));
        const auto idx = to_int(t);
        if (!idx || *idx == 0) throw error_at_line(src, lines.number(), "bad vertex index " + quote(tok[k]));
        long long zero_based = *idx > 0 ? *idx - 1 : static_cast<long long>(m.vertices.size()) + *idx;
        if (zero_based < 0)
          throw error_at_line(src, lines.number(),
                              "relative vertex index " + std::to_string(*idx) + " out of range (" +
                                  std::to_string(m.vertices.size()) + " vertices so far)");
        if (zero_based > 0xFFFFFFF0LL)
          throw error_at_line(src, lines.number(), "vertex index " + std::to_string(*idx) + " out of range");
        if (zero_based + 1 > max_index_seen) {
          max_index_seen = zero_based + 1;
          max_index_line = lines.number();
        }
        face.push_back(static_cast<std::uint32_t>(zero_based));
      }
      if (face.size() < 3)
        throw error_at_line(src, lines.number(),
                            "face has " + std::to_string(face.size()) + " vertices (need at least 3)");
      m.faces.push_back(std::move(face));
      face_lines.push_back(lines.number());
    }
  }
  if (max_index_seen > static_cast<long long>(m.vertices.size()))
    throw error_at_line(src, max_index_line,
                        "vertex index " + std::to_string(max_index_seen) + " out of range (" +
                            std::to_string(m.vertices.size()) + " vertices)");
  for (std::size_t f = 0; f < m.faces.size(); ++f)
    if (auto e = check(m.faces[f], m.vertices.size()); !e.empty()) throw error_at_line(src, face_lines[f], e);
  return m;
}

// ---------------------------------------------------------------------------------------------------------
// STL (ascii and binary), welded.

struct Welder {
  struct Key {
    std::array<std::uint64_t, 3> bits;
    bool operator==(const Key&) const = default;
  };
  struct Hash {
    std::size_t operator()(const Key& k) const {
      std::uint64_t h = 1469598103934665603ULL;
      for (auto b : k.bits) h = (h ^ b) * 1099511628211ULL ^ (h >> 29);
      return static_cast<std::size_t>(h);
    }
  };
  std::unordered_map<Key, std::uint32_t, Hash> index;
  Mesh* mesh;
  explicit Welder(Mesh& m) : mesh(&m) {}
  std::uint32_t add(const Vec3& v) {
    // +0.0 and -0.0 are the same point.
    const Vec3 w(v.x() == 0 ? 0.0 : v.x(), v.y() == 0 ? 0.0 : v.y(), v.z() == 0 ? 0.0 : v.z());
    const Key k{{std::bit_cast<std::uint64_t>(w.x()), std::bit_cast<std::uint64_t>(w.y()),
                 std::bit_cast<std::uint64_t>(w.z())}};
    auto [it, inserted] = index.emplace(k, static_cast<std::uint32_t>(mesh->vertices.size()));
    if (inserted) mesh->vertices.push_back(w);
    return it->second;
  }
  void triangle(const std::array<Vec3, 3>& t) {
    std::vector<std::uint32_t> f{add(t[0]), add(t[1]), add(t[2])};
    if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2]) return;  // collapsed triangle: no face
    mesh->faces.push_back(std::move(f));
  }
};

std::uint32_t read_le32(const unsigned char* p) {
  return static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) << 8 |
         static_cast<std::uint32_t>(p[2]) << 16 | static_cast<std::uint32_t>(p[3]) << 24;
}
float read_lef32(const unsigned char* p) { return std::bit_cast<float>(read_le32(p)); }

Mesh parse_stl_binary(std::string_view bytes, const std::string& src) {
  Mesh m;
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  if (bytes.size() < 84)
    throw error_at_offset(src, bytes.size(), "binary STL shorter than its 84-byte header");
  const std::uint32_t n = read_le32(p + 80);
  const std::uint64_t need = 84ULL + 50ULL * n;
  if (need != bytes.size())
    throw error_at_offset(src, 80,
                          "binary STL declares " + std::to_string(n) + " triangles (" + std::to_string(need) +
                              " bytes) but the file has " + std::to_string(bytes.size()) + " bytes");
  if (n == 0) throw error_at_offset(src, 80, "binary STL has no triangles");
  Welder weld(m);
  m.vertices.reserve(n / 2 + 3);
  m.faces.reserve(n);
  for (std::uint32_t t = 0; t < n; ++t) {
    const std::size_t off = 84 + 50 * static_cast<std::size_t>(t);
    std::array<Vec3, 3> tri;
    for (int k = 0; k < 3; ++k) {
      const std::size_t vo = off + 12 + 12 * static_cast<std::size_t>(k);
      tri[static_cast<std::size_t>(k)] =
          Vec3(read_lef32(p + vo), read_lef32(p + vo + 4), read_lef32(p + vo + 8));
      if (auto e = check_vertex(tri[static_cast<std::size_t>(k)]); !e.empty())
        throw error_at_offset(src, vo, "triangle " + std::to_string(t) + ": " + e);
    }
    weld.triangle(tri);
  }
  return m;
}

Mesh parse_stl_ascii(std::string_view text, const std::string& src) {
  Mesh m;
  Welder weld(m);
  // Skip "solid [name]" line.
  std::size_t first_nl = text.find('\n');
  if (first_nl == std::string_view::npos) throw error_at_line(src, 1, "ASCII STL has no facets");
  Tokens t(text.substr(first_nl + 1), 2);
  std::string_view tok;
  auto expect = [&](std::string_view word) {
    if (!t.next(tok)) throw error_at_line(src, t.line(), "file ends, expected '" + std::string(word) + "'");
    if (lower(tok) != word)
      throw error_at_line(src, t.line(), "expected '" + std::string(word) + "', found " + quote(tok));
  };
  auto number = [&]() {
    if (!t.next(tok)) throw error_at_line(src, t.line(), "file ends, expected a number");
    const auto d = to_double(tok);
    if (!d) throw error_at_line(src, t.line(), "bad number " + quote(tok));
    return *d;
  };
  bool ended = false;
  std::size_t facets = 0;
  while (t.next(tok)) {
    const std::string w = lower(tok);
    if (w == "endsolid") {
      ended = true;
      break;
    }
    if (w != "facet")
      throw error_at_line(src, t.line(), "expected 'facet' or 'endsolid', found " + quote(tok));
    expect("normal");
    for (int k = 0; k < 3; ++k) number();
    expect("outer");
    expect("loop");
    std::array<Vec3, 3> tri;
    for (int k = 0; k < 3; ++k) {
      expect("vertex");
      Vec3 v;
      v.x() = number();
      v.y() = number();
      v.z() = number();
      if (auto e = check_vertex(v); !e.empty()) throw error_at_line(src, t.line(), "vertex: " + e);
      tri[static_cast<std::size_t>(k)] = v;
    }
    expect("endloop");
    expect("endfacet");
    weld.triangle(tri);
    ++facets;
  }
  if (!ended) throw error_at_line(src, t.line(), "file ends without 'endsolid'");
  if (facets == 0) throw error_at_line(src, t.line(), "ASCII STL has no facets");
  return m;
}

Mesh parse_stl(std::string_view bytes, const std::string& src) {
  if (bytes.size() >= 84) {
    const std::uint32_t n = read_le32(reinterpret_cast<const unsigned char*>(bytes.data()) + 80);
    if (84ULL + 50ULL * n == bytes.size()) return parse_stl_binary(bytes, src);
  }
  std::size_t i = 0;
  while (i < bytes.size() && (is_space(bytes[i]) || bytes[i] == '\n')) ++i;
  // Binary files may start with "solid" too: ASCII needs the keywords and no NUL bytes.
  if (bytes.size() - i >= 5 && lower(bytes.substr(i, 5)) == "solid" &&
      (bytes.size() < 84 ||
       (bytes.find('\0') == std::string_view::npos &&
        lower(bytes.substr(0, std::min<std::size_t>(bytes.size(), 4096))).find("facet") !=
            std::string::npos)))
    return parse_stl_ascii(bytes.substr(i), src);
  if (bytes.empty()) throw Error(src + ": empty STL file");
  return parse_stl_binary(bytes, src);  // reports the size mismatch
}

// ---------------------------------------------------------------------------------------------------------
// PLY

enum class PlyType { I8, U8, I16, U16, I32, U32, F32, F64 };

std::optional<PlyType> ply_type(std::string_view s) {
  static const std::map<std::string, PlyType, std::less<>> types{
      {"char", PlyType::I8},    {"int8", PlyType::I8},     {"uchar", PlyType::U8},
      {"uint8", PlyType::U8},   {"short", PlyType::I16},   {"int16", PlyType::I16},
      {"ushort", PlyType::U16}, {"uint16", PlyType::U16},  {"int", PlyType::I32},
      {"int32", PlyType::I32},  {"uint", PlyType::U32},    {"uint32", PlyType::U32},
      {"float", PlyType::F32},  {"float32", PlyType::F32}, {"double", PlyType::F64},
      {"float64", PlyType::F64}};
  const auto it = types.find(s);
  if (it == types.end()) return std::nullopt;
  return it->second;
}

std::size_t ply_size(PlyType t) {
  switch (t) {
    case PlyType::I8:
    case PlyType::U8:
      return 1;
    case PlyType::I16:
    case PlyType::U16:
      return 2;
    case PlyType::I32:
    case PlyType::U32:
    case PlyType::F32:
      return 4;
    case PlyType::F64:
      return 8;
  }
  return 1;
}

bool ply_is_integer(PlyType t) { return t != PlyType::F32 && t != PlyType::F64; }

struct PlyProperty {
  std::string name;
  bool is_list = false;
  PlyType count_type = PlyType::U8;
  PlyType type = PlyType::F32;
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> props;
};

enum class PlyFormat { Ascii, BinaryLE, BinaryBE };

// Reads one scalar from the body; ASCII by tokens, binary by bytes.
class PlyBody {
 public:
  PlyBody(std::string_view body, std::size_t base, std::uint64_t first_line, PlyFormat fmt,
          const std::string& src)
      : body_(body), base_(base), tokens_(body, first_line), fmt_(fmt), src_(src) {}

  double read(PlyType t) {
    if (fmt_ == PlyFormat::Ascii) {
      std::string_view tok;
      if (!tokens_.next(tok)) throw error_at_line(src_, tokens_.line(), "file ends inside the PLY data");
      if (ply_is_integer(t)) {
        const auto v = to_int(tok);
        if (!v) throw error_at_line(src_, tokens_.line(), "bad integer " + quote(tok));
        return static_cast<double>(*v);
      }
      const auto v = to_double(tok);
      if (!v) throw error_at_line(src_, tokens_.line(), "bad number " + quote(tok));
      return *v;
    }
    const std::size_t n = ply_size(t);
    if (pos_ + n > body_.size()) throw error_at_offset(src_, base_ + pos_, "file ends inside the PLY data");
    unsigned char b[8];
    std::memcpy(b, body_.data() + pos_, n);
    if (fmt_ == PlyFormat::BinaryBE) std::reverse(b, b + n);
    pos_ += n;
    switch (t) {
      case PlyType::I8:
        return static_cast<std::int8_t>(b[0]);
      case PlyType::U8:
        return b[0];
      case PlyType::I16: {
        std::int16_t v;
        std::memcpy(&v, b, 2);
        return v;
      }
      case PlyType::U16: {
        std::uint16_t v;
        std::memcpy(&v, b, 2);
        return v;
      }
      case PlyType::I32: {
        std::int32_t v;
        std::memcpy(&v, b, 4);
        return v;
      }
      case PlyType::U32: {
        std::uint32_t v;
        std::memcpy(&v, b, 4);
        return v;
      }
      case PlyType::F32: {
        float v;
        std::memcpy(&v, b, 4);
        return v;
      }
      case PlyType::F64: {
        double v;
        std::memcpy(&v, b, 8);
        return v;
      }
    }
    return 0.0;
  }
  // Error at the current position.
  Error error(const std::string& what) const {
    if (fmt_ == PlyFormat::Ascii) return error_at_line(src_, tokens_.line(), what);
    return error_at_offset(src_, base_ + pos_, what);
  }
  std::size_t remaining() const { return fmt_ == PlyFormat::Ascii ? body_.size() : body_.size() - pos_; }
  bool binary() const { return fmt_ != PlyFormat::Ascii; }

 private:
  std::string_view body_;
  std::size_t base_;
  std::size_t pos_ = 0;
  Tokens tokens_;
  PlyFormat fmt_;
  const std::string& src_;
};

Mesh parse_ply(std::string_view bytes, const std::string& src) {
  Lines lines(bytes);
  std::string_view line;
  std::vector<std::string_view> tok;
  if (!lines.next(line) || split(line, tok, 0) != 1 || tok[0] != "ply")
    throw error_at_line(src, 1, "not a PLY file (no 'ply' magic)");
  std::optional<PlyFormat> fmt;
  std::vector<PlyElement> elements;
  bool header_done = false;
  while (lines.next(line)) {
    if (split(line, tok, 0) == 0) continue;
    if (tok[0] == "comment" || tok[0] == "obj_info") continue;
    if (tok[0] == "end_header") {
      header_done = true;
      break;
    }
    if (tok[0] == "format") {
      if (tok.size() != 3) throw error_at_line(src, lines.number(), "expected 'format <type> 1.0'");
      if (tok[1] == "ascii")
        fmt = PlyFormat::Ascii;
      else if (tok[1] == "binary_little_endian")
        fmt = PlyFormat::BinaryLE;
      else if (tok[1] == "binary_big_endian")
        fmt = PlyFormat::BinaryBE;
      else
        throw error_at_line(src, lines.number(), "unknown PLY format " + quote(tok[1]));
    } else if (tok[0] == "element") {
      if (tok.size() != 3) throw error_at_line(src, lines.number(), "expected 'element <name> <count>'");
      const auto n = to_int(tok[2]);
      if (!n || *n < 0) throw error_at_line(src, lines.number(), "bad element count " + quote(tok[2]));
      elements.push_back({std::string(tok[1]), static_cast<std::uint64_t>(*n), {}});
    } else if (tok[0] == "property") {
      if (elements.empty()) throw error_at_line(src, lines.number(), "property before any element");
      PlyProperty p;
      if (tok.size() == 5 && tok[1] == "list") {
        const auto ct = ply_type(tok[2]);
        const auto it = ply_type(tok[3]);
        if (!ct || !ply_is_integer(*ct))
          throw error_at_line(src, lines.number(), "bad list count type " + quote(tok[2]));
        if (!it) throw error_at_line(src, lines.number(), "unknown property type " + quote(tok[3]));
        p.is_list = true;
        p.count_type = *ct;
        p.type = *it;
        p.name = tok[4];
      } else if (tok.size() == 3) {
        const auto t = ply_type(tok[1]);
        if (!t) throw error_at_line(src, lines.number(), "unknown property type " + quote(tok[1]));
        p.type = *t;
        p.name = tok[2];
      } else {
        throw error_at_line(src, lines.number(),
                            "expected 'property <type> <name>' or 'property list <t> <t> <name>'");
      }
      elements.back().props.push_back(std::move(p));
    } else {
      throw error_at_line(src, lines.number(), "unknown PLY header keyword " + quote(tok[0]));
    }
  }
  if (!header_done) throw error_at_line(src, lines.number(), "PLY header has no 'end_header'");
  if (!fmt) throw error_at_line(src, lines.number(), "PLY header has no 'format' line");

  const std::size_t body_start = lines.position();
  PlyBody body(bytes.substr(body_start), body_start, lines.number() + 1, *fmt, src);
  Mesh m;
  FaceCheck check;
  bool have_vertex = false, have_face = false;
  std::vector<std::uint32_t> face;
  for (const PlyElement& el : elements) {
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

}  // namespace

MeshFormat mesh_format_from_path(const std::filesystem::path& path) {
  const std::string ext = lower(path.extension().string());
  if (ext == ".off") return MeshFormat::Off;
  if (ext == ".obj") return MeshFormat::Obj;
  if (ext == ".stl") return MeshFormat::Stl;
  if (ext == ".ply") return MeshFormat::Ply;
  throw Error(path.string() + ": unknown mesh format '" + ext + "' (expected .off, .obj, .stl or .ply)");
}

Mesh parse_mesh(std::string_view bytes, MeshFormat format, const std::string& source,
                const std::string& name) {
  if (bytes.empty()) throw Error(source + ": empty file");
  Mesh m;
  switch (format) {
    case MeshFormat::Off:
      m = parse_off(bytes, source);
      break;
    case MeshFormat::Obj:
      m = parse_obj(bytes, source);
      break;
    case MeshFormat::Stl:
      m = parse_stl(bytes, source);
      break;
    case MeshFormat::Ply:
      m = parse_ply(bytes, source);
      break;
  }
  check_not_empty(m, source);
  m.name = name;
  return m;
}

Mesh read_mesh(const std::filesystem::path& path) {
  const MeshFormat fmt = mesh_format_from_path(path);
  std::error_code ec;
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_regular_file(path, ec))
    throw Error(path.string() + ": not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path.string() + ": cannot open mesh file");
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw Error(path.string() + ": read error");
  return parse_mesh(bytes, fmt, path.string(), path.stem().string());
}

std::string check_closed_manifold(const Mesh& mesh) {
  // Directed edge (a, b) -> number of uses; a closed oriented manifold uses each directed edge once and
  // its reverse once.
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const auto& face = mesh.faces[f];
    for (std::size_t k = 0; k < face.size(); ++k) {
      const std::uint32_t a = face[k], b = face[(k + 1) % face.size()];
      if (++directed[{a, b}] > 1)
        return "edge " + std::to_string(a) + "-" + std::to_string(b) +
               " is used twice in the same direction (face " + std::to_string(f) +
               "): inconsistent orientation or non-manifold";
    }
  }
  for (const auto& [e, n] : directed) {
    (void)n;
    if (directed.find({e.second, e.first}) == directed.end())
      return "edge " + std::to_string(e.first) + "-" + std::to_string(e.second) +
             " has only one face: the mesh is not closed";
  }
  return {};
}

double mesh_signed_volume(const Mesh& mesh) {
  double v6 = 0.0;
  for (const auto& face : mesh.faces) {
    if (face.size() < 3) continue;
    const Vec3& a = mesh.vertices[face[0]];
    for (std::size_t k = 1; k + 1 < face.size(); ++k)
      v6 += a.dot(mesh.vertices[face[k]].cross(mesh.vertices[face[k + 1]]));
  }
  return v6 / 6.0;
}

}  // namespace fs
