#include "host/recognize/scene_prep.hpp"

#include <algorithm>
#include <cmath>

namespace fs::host::rec {

void absorb_into_supernode(Pfrg& g, int id) {
  int super = -1;
  for (const auto& n : g.nodes)
    if (n.supernode) super = n.id;
  if (super < 0) {
    super = 0;
    for (const auto& n : g.nodes) super = std::max(super, n.id + 1);
    PfrgNode s;
    s.id = super;
    s.supernode = true;
    g.nodes.push_back(s);
  }
  // Re-route arcs; then merge parallel arcs to the supernode.
  for (auto& a : g.arcs) {
    if (a.a == id) a.a = super;
    if (a.b == id) a.b = super;
  }
  std::erase_if(g.arcs, [&](const PfrgArc& a) { return a.a == a.b; });
  for (std::size_t i = 0; i < g.arcs.size(); ++i) {
    for (std::size_t j = i + 1; j < g.arcs.size();) {
      const bool same = (g.arcs[i].a == g.arcs[j].a && g.arcs[i].b == g.arcs[j].b) ||
                        (g.arcs[i].a == g.arcs[j].b && g.arcs[i].b == g.arcs[j].a);
      if (same) {
        g.arcs[i].border += g.arcs[j].border;
        g.arcs[j] = g.arcs.back();
        g.arcs.pop_back();
      } else {
        ++j;
      }
    }
  }
  std::erase_if(g.nodes, [&](const PfrgNode& n) { return n.id == id; });
}

int remove_table(Pfrg& g, const Plane* table, const Vec3& viewpoint, double angle_deg, double dist_mm,
                 Plane* found) {
  const double cos_max = std::cos(angle_deg * M_PI / 180.0);
  int best = -1;
  double best_area = 0.0, total = 0.0;
  for (const auto& n : g.nodes) {
    if (n.supernode) continue;
    total += n.area;
    if (table) {
      if (!n.has_plane) continue;
      // Same plane, either orientation of the normal.
      const double c = n.normal.dot(table->n);
      const double d = c >= 0 ? n.offset - table->d : n.offset + table->d;
      if (std::abs(c) >= cos_max && std::abs(d) <= dist_mm && n.area > best_area) {
        best = n.id;
        best_area = n.area;
      }
    } else if (n.area > best_area) {
      const bool faces_viewer = !n.has_plane || n.normal.dot(viewpoint - n.centroid) > 0;
      if (faces_viewer) {
        best = n.id;
        best_area = n.area;
      }
    }
  }
  if (best < 0) return -1;
  if (!table && best_area < 0.25 * total) return -1;
  if (found) {
    for (const auto& n : g.nodes)
      if (n.id == best) {
        // The measured plane (the given one may be nominal); normal toward the viewpoint.
        const bool flip = n.has_plane ? n.normal.dot(viewpoint) - n.offset < 0 : false;
        found->n = flip ? Vec3(-n.normal) : n.normal;
        found->d = flip ? -n.offset : n.offset;
        if (!n.has_plane && table) *found = *table;
      }
  }
  absorb_into_supernode(g, best);
  return best;
}

}  // namespace fs::host::rec
