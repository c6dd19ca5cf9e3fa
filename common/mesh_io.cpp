#include "common/mesh_io.hpp"

#include <map>

#include "common/error.hpp"
#include "common/formats/mesh_formats.hpp"
#include "common/formats/tokenizer.hpp"
#include "common/input_file.hpp"

namespace fs {

MeshFormat mesh_format_from_path(const std::filesystem::path& path) {
  const std::string ext = formats::lower(path.extension().string());
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
      m = formats::parse_off(bytes, source);
      break;
    case MeshFormat::Obj:
      m = formats::parse_obj(bytes, source);
      break;
    case MeshFormat::Stl:
      m = formats::parse_stl(bytes, source);
      break;
    case MeshFormat::Ply:
      m = formats::parse_ply_mesh(bytes, source);
      break;
  }
  formats::check_not_empty(m, source);
  m.name = name;
  return m;
}

Mesh read_mesh(const std::filesystem::path& path) {
  const MeshFormat fmt = mesh_format_from_path(path);
  const std::string bytes = read_input_file(path, kMaxMeshFileBytes, "mesh file");
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
