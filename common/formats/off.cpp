#include "common/formats/mesh_formats.hpp"

#include <string>
#include <utility>
#include <vector>

#include "common/formats/tokenizer.hpp"

namespace fs::formats {

// OFF: [C|N|ST...]OFF header, "nv nf ne", nv vertex lines (x y z [extra]), nf face lines (n i1..in [colour]).

Mesh parse_off(std::string_view text, const std::string& src) {
  Mesh m;
  TextLines lines(text, src, TextStyle::Loose, '#');
  const std::vector<std::string_view>& tok = lines.tokens();
  auto next_content = [&]() -> bool {
    while (lines.next())
      if (!tok.empty()) return true;
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
  const auto remaining = static_cast<long long>(text.size() - lines.offset());
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

}  // namespace fs::formats
