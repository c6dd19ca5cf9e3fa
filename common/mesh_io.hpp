#pragma once
// Mesh readers behind fs::read_mesh (common/mesh.hpp), usable on memory (fuzzing, embedded data), and mesh
// validity checks. Every reader rejects: no vertices or no faces, counts that the file cannot hold,
// non-finite coordinates, faces with fewer than 3 vertices, repeated or out-of-range indices. Errors are
// fs::Error "file:LINE: what" (text formats) or "file: at byte N: what" (binary formats).
#include <filesystem>
#include <string>
#include <string_view>

#include "common/mesh.hpp"

namespace fs {

enum class MeshFormat { Off, Obj, Stl, Ply };

// By extension, case-insensitive: .off .obj .stl .ply. Throws fs::Error for anything else.
MeshFormat mesh_format_from_path(const std::filesystem::path& path);

// Parses a whole file held in memory. `source` names it in error messages; the mesh is named `name`.
// STL triangle soups are welded on exactly equal coordinates; triangles that collapse are dropped.
Mesh parse_mesh(std::string_view bytes, MeshFormat format, const std::string& source,
                const std::string& name = {});

// "" when every edge is shared by exactly two faces that traverse it in opposite directions (a closed,
// consistently oriented 2-manifold); otherwise a message naming the first offending edge.
std::string check_closed_manifold(const Mesh& mesh);

// Signed volume (positive for outward-oriented closed meshes), by the divergence theorem over fan triangles.
double mesh_signed_volume(const Mesh& mesh);

}  // namespace fs
