#pragma once
// Exact matching (thesis ch. 5.3, 6): Ullmann's correspondence search with the node-degree condition and
// structural refinement (forward-checking neighbourhood condition) on non-attributed graphs. Supernodes and
// their arcs are ignored.
#include <cstdint>
#include <functional>
#include <span>
#include <utility>

#include "host/pfrg/pfrg.hpp"

namespace fs::host::match {

enum class ExactMode {
  kInduced,       // subgraph isomorphism: T[i,j] == R'[i,j] for all test node pairs (ch. 5.3.1)
  kMonomorphism,  // subgraph check: every test arc has a reference arc (non-induced)
};

struct ExactStats {
  std::uint64_t count = 0;       // mappings found
  std::uint64_t tree_nodes = 0;  // search tree states visited
  std::uint64_t refinement_removals = 0;
};

// A mapping: pairs (test node id, reference node id) in test node order.
using ExactMappingFn = std::function<void(std::span<const std::pair<int, int>>)>;

// Counts (and reports via on_mapping when given) all injective mappings of the test graph into the reference
// graph under `mode`. Throws fs::Error for graphs over the size limit.
ExactStats count_isomorphisms(const Pfrg& test, const Pfrg& ref, ExactMode mode,
                              const ExactMappingFn& on_mapping = {});

}  // namespace fs::host::match
