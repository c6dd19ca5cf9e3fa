#include "common/formats/mesh_formats.hpp"

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "common/formats/tokenizer.hpp"

namespace fs::formats {

// OBJ: "v x y z [w]" and "f a a/b a//c a/b/c ..." (1-based, negative = relative); everything else ignored.

Mesh parse_obj(std::string_view text, const std::string& src) {
  Mesh m;
  TextLines lines(text, src, TextStyle::Loose, '#');
  const std::vector<std::string_view>& tok = lines.tokens();
  FaceCheck check;
  std::vector<std::uint64_t> face_lines;
  long long max_index_seen = 0;
  std::uint64_t max_index_line = 0;
  while (lines.next()) {
    if (tok.empty()) continue;
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

}  // namespace fs::formats
