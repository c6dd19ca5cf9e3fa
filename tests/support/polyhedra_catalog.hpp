#pragma once
// The 120 polyhedra of ../shared/data as the recognition tests and benchmarks place them (make_catalog, seed
// 1) and their library (one model per catalog entry, same order), built once per process.
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

inline const PolyhedraCatalog& polyhedra_catalog() {
  static const PolyhedraCatalog b = [] {
    PolyhedraCatalog x;
    x.catalog = sim::make_catalog(sim::read_catalog_meshes(shared_data() / "polyhedra/polyhedra-viewer/off"),
                                  {.seed = 1});
    for (const auto& e : x.catalog) x.library.add(host::build_model(e.mesh));
    return x;
  }();
  return b;
}

}  // namespace fs::test
