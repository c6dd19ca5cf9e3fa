#pragma once
// The 120 polyhedra of ../shared/data as the recognition tests and benchmarks place them (make_catalog, seed
// 1 unless named: bench_recognition --seed S sizes them with S) and their library (one model per catalog
// entry, same order), built once per process and seed.
#include <cstdint>
#include <map>
#include <mutex>
#include <vector>

#include "host/library/library.hpp"
#include "host/library/model.hpp"
#include "hw-sim/scene/random_scene.hpp"
#include "support/test_paths.hpp"

namespace fs::test {

struct PolyhedraCatalog {
  std::vector<sim::CatalogEntry> catalog;
  host::Library library;
};

inline const PolyhedraCatalog& polyhedra_catalog(std::uint64_t seed = 1) {
  static std::mutex m;
  static std::map<std::uint64_t, PolyhedraCatalog> built;  // map nodes stay put: references stay valid
  const std::lock_guard<std::mutex> lock(m);
  auto it = built.find(seed);
  if (it == built.end()) {
    PolyhedraCatalog x;
    x.catalog = sim::make_catalog(sim::read_catalog_meshes(shared_data() / "polyhedra/polyhedra-viewer/off"),
                                  {.seed = seed});
    for (const auto& e : x.catalog) x.library.add(host::build_model(e.mesh));
    it = built.emplace(seed, std::move(x)).first;
  }
  return it->second;
}

}  // namespace fs::test
