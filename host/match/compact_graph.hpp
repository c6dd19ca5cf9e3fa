#pragma once
// A PFRG in the matchers' working form: nodes re-indexed 0..n-1, adjacency as bitsets, border lengths in a
// dense matrix. Fixed capacity (kMaxNodes): loading a graph does not allocate.
#include <array>

#include "common/calibration.hpp"
#include "host/match/node_set.hpp"
#include "host/pfrg/pfrg.hpp"

namespace fs::host::match {

struct CompactGraph {
  int n = 0;
  std::array<int, kMaxNodes> id{};  // PFRG node id of index i
  std::array<bool, kMaxNodes> supernode{};
  std::array<double, kMaxNodes> area{};
  std::array<Vec3, kMaxNodes> normal{};
  std::array<int, kMaxNodes> degree{};  // number of adjacent nodes (supernode included)
  std::array<NodeSet, kMaxNodes> adj{};
  NodeSet real;                                                  // non-supernode nodes
  std::array<std::array<float, kMaxNodes>, kMaxNodes> border{};  // mm, 0 when not adjacent
  Vec3 observer = Vec3::Zero();                                  // unit, toward the sensor (scene graphs)

  // Throws fs::Error (naming g.name) when g has more than kMaxNodes nodes or an arc names an unknown node.
  // include_supernodes = false drops supernodes and their arcs (exact matching of pure graphs).
  void load(const Pfrg& g, bool include_supernodes = true);
  int index_of(int node_id) const;  // -1 when absent
};

// Area of real node i plus that of each real neighbour whose normal lies within fold_deg of i's (the surface
// a segmentation region may grow over across shallow folds; MatchParams::th_area_fold_deg). fold_deg <= 0:
// the node's own area.
double area_with_shallow_folds(const CompactGraph& g, int i, double fold_deg);

}  // namespace fs::host::match
