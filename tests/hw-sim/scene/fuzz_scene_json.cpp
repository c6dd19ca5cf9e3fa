// Fuzz target: scene JSON (objects, poses, table, scanner overrides). Any input must parse or raise
// fs::Error; model paths resolve against the shipped scenes folder, so inputs can name the real meshes.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "common/error.hpp"
#include "hw-sim/scene/scene.hpp"
#include "support/test_paths.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const auto doc = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return 0;
  try {
    const fs::sim::Scene s = fs::sim::parse_scene(doc, fs::test::source_dir() / "hw-sim/scenes", "fuzz.json");
    for (const auto& o : s.objects)
      if (o.faces.size() != o.mesh.faces.size()) std::abort();
  } catch (const fs::Error&) {
  }
  return 0;
}
