#include "common/formats/mesh_formats.hpp"

#include <array>
#include <bit>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "common/formats/tokenizer.hpp"

namespace fs::formats {

namespace {

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
  TextTokens t(text.substr(first_nl + 1), 0, 2, TextStyle::Loose);
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

}  // namespace

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

}  // namespace fs::formats
