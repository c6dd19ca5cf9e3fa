// Fuzz target: meshes from bytes (OFF text) through build_model; bad meshes give fs::Error, never a crash.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "common/error.hpp"
#include "common/mesh_io.hpp"
#include "host/library/model.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 1 << 16) return 0;
  try {
    const fs::Mesh mesh = fs::parse_mesh(std::string_view(reinterpret_cast<const char*>(data), size),
                                         fs::MeshFormat::Off, "fuzz.off", "fuzz");
    fs::host::BuildOptions o;
    o.allow_open = (size & 1) != 0;
    (void)fs::host::build_model(mesh, o);
  } catch (const fs::Error&) {
  }
  return 0;
}
