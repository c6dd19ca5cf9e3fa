#pragma once
// The mesh readers of one format each behind fs::parse_mesh (common/mesh_io.hpp), and the checks they share.
#include <algorithm>
#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include "common/error.hpp"
#include "common/mesh.hpp"

namespace fs::formats {

Mesh parse_off(std::string_view text, const std::string& src);        // off.cpp
Mesh parse_obj(std::string_view text, const std::string& src);        // obj.cpp
Mesh parse_stl(std::string_view bytes, const std::string& src);       // stl.cpp (ascii and binary)
Mesh parse_ply_mesh(std::string_view bytes, const std::string& src);  // ply_mesh.cpp

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

inline std::string check_vertex(const Vec3& v) {
  if (!std::isfinite(v.x()) || !std::isfinite(v.y()) || !std::isfinite(v.z())) return "non-finite coordinate";
  return {};
}

inline void check_not_empty(const Mesh& m, const std::string& source) {
  if (m.vertices.empty()) throw Error(source + ": mesh has no vertices");
  if (m.faces.empty()) throw Error(source + ": mesh has no faces");
}

}  // namespace fs::formats
