// Fuzz target: the mesh readers (OFF, OBJ, STL, PLY). The first byte picks the format, the rest is the file.
// Any input must either parse or raise fs::Error; a parsed mesh must be internally consistent.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "common/error.hpp"
#include "common/mesh_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const auto format = static_cast<fs::MeshFormat>(data[0] % 4);
  const std::string_view bytes(reinterpret_cast<const char*>(data + 1), size - 1);
  try {
    const fs::Mesh m = fs::parse_mesh(bytes, format, "fuzz");
    if (m.vertices.empty() || m.faces.empty()) std::abort();
    for (const auto& f : m.faces) {
      if (f.size() < 3) std::abort();
      for (auto i : f)
        if (i >= m.vertices.size()) std::abort();
    }
    (void)fs::check_closed_manifold(m);
  } catch (const fs::Error&) {
  }
  return 0;
}
