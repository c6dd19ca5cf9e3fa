#pragma once
// The 120 polyhedra of ../shared/data as the recognition tests and benchmarks place them (make_catalog, seed
// 1 unless named: bench_recognition --seed S sizes them with S, --sizes draws the sizes) and their library
// (one model per catalog entry, same order), built once per process and seed.
#include <cstdint>
#include <map>
#include <mutex>
#include <tuple>
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

// sizes: the largest extent of each solid, drawn from [min_size_mm, max_size_mm] (bench_recognition --sizes).
inline const PolyhedraCatalog& polyhedra_catalog(std::uint64_t seed = 1, double min_size_mm = 40.0,
                                                 double max_size_mm = 80.0) {
  static std::mutex m;
  // map nodes stay put: references stay valid
  static std::map<std::tuple<std::uint64_t, double, double>, PolyhedraCatalog> built;
  const std::lock_guard<std::mutex> lock(m);
  const auto key = std::make_tuple(seed, min_size_mm, max_size_mm);
  auto it = built.find(key);
  if (it == built.end()) {
    PolyhedraCatalog x;
    x.catalog = sim::make_catalog(sim::read_catalog_meshes(shared_data() / "polyhedra/polyhedra-viewer/off"),
                                  {.min_size_mm = min_size_mm, .max_size_mm = max_size_mm, .seed = seed});
    for (const auto& e : x.catalog) x.library.add(host::build_model(e.mesh));
    it = built.emplace(key, std::move(x)).first;
  }
  return it->second;
}

}  // namespace fs::test
