#pragma once
// The scene PFRG from a segmentation, with the high-level preprocessing of thesis ch. 3.5.2 (fig. 3.12):
//  1. complete graph: borders to NIL cells and to the image boundary become arcs to one supernode (id 0);
//  2. eliminate border regions: an unknown region whose neighbours are exactly two known regions i, k
//     (no other unknown region) is compressed to zero width when the border i-k already exists: the mean of
//     its two side borders is added to that border, the region and its arcs disappear (jump edges survive);
//  3. eliminate null nodes: the remaining unknown regions are removed; an unknown region that touches NIL /
//     the image boundary is part of the unknown area, so its arcs to known regions move to the supernode,
//     other ones (holes, fragments between known faces) are dropped with their arcs;
//  4. merge parallel arcs (border lengths summed).
// Node ids: 0 = supernode, region r -> r + 1 (so ids match Segmentation labels + 1).
// No heap allocation after construction for segmentations within the limits given.
#include <cstdint>
#include <vector>

#include "host/pfrg/pfrg.hpp"
#include "host/segment/segmentation.hpp"

namespace fs::host::seg {

struct PreprocessStats {
  int known_regions = 0;
  int unknown_regions = 0;
  int border_regions_eliminated = 0;
  int null_nodes_to_supernode = 0;
  int null_nodes_dropped = 0;
  int arcs_before_merge = 0;
  int arcs = 0;
};

class ScenePfrgBuilder {
 public:
  explicit ScenePfrgBuilder(std::size_t max_regions = 8192, std::size_t max_borders = 32768);
  // Reserves `g` (nodes / arcs) for the limits.
  void prepare(Pfrg& g) const;
  void build(const Segmentation& s, Pfrg& g, PreprocessStats* stats = nullptr);

  // Borders between two regions made of fewer grid cell edges than this are ignored (e.g. opposite pyramid
  // faces touching at the apex through one cell corner).
  std::uint32_t min_border_edges = 3;

 private:
  struct WArc {
    std::int32_t a, b;  // region ids, or the supernode index sn_ (a < b after normalization)
    double len;
    bool alive;
  };
  std::size_t max_regions_, max_borders_;
  std::vector<WArc> arcs_;
  std::vector<std::int32_t> deg_, off_, adj_;  // CSR adjacency: arc indices per node
};

}  // namespace fs::host::seg
