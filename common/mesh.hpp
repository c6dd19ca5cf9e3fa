#pragma once
// Polygon meshes (CAD models, scene objects). Readers for OFF, OBJ, STL (ascii + binary), PLY (ascii +
// binary) live in common/mesh_io.cpp; malformed files raise fs::Error naming the file and line/offset.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "common/calibration.hpp"

namespace fs {

struct Mesh {
  std::string name;  // file stem by default
  std::vector<Vec3> vertices;
  std::vector<std::vector<std::uint32_t>> faces;  // polygons, indices into vertices
};

// Reads a mesh by file extension (.off .obj .stl .ply, case-insensitive).
Mesh read_mesh(const std::filesystem::path& path);

}  // namespace fs
