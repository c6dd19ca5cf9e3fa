#pragma once
// Scene PFRG preparation before matching: the support plane (table) is not an object face; it is absorbed
// into the supernode (its arcs become arcs to the supernode, parallel arcs merged).
#include "common/calibration.hpp"
#include "host/pfrg/pfrg.hpp"

namespace fs::host::rec {

// Absorbs node `id` into the supernode (id 0 is created when the graph has none). No allocation when the
// graph's arc vector has spare capacity for one arc per neighbour.
void absorb_into_supernode(Pfrg& g, int id);

// Finds the table node (plane within angle_deg / dist_mm of `table` when given; otherwise the largest face
// when it holds >= 25% of the known area and faces the viewpoint) and absorbs it. Returns its id or -1.
// `found` (optional) receives the table's plane, its normal toward the viewpoint (the scene's "up").
int remove_table(Pfrg& g, const Plane* table, const Vec3& viewpoint, double angle_deg, double dist_mm,
                 Plane* found = nullptr);

}  // namespace fs::host::rec
