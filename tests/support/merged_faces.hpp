#pragma once
// A PFRG as a segmentation gives it when one region grows over two adjacent faces (a shallow fold): face
// `gone` joins face `kept`, which takes its area (its normal stays); their shared arc goes, and gone's other
// arcs move to kept (joining kept's own arc to the same node, borders added).
#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <utility>

#include "host/pfrg/pfrg.hpp"

namespace fs::test {

inline host::Pfrg merged_faces(const host::Pfrg& g, int kept, int gone) {
  host::Pfrg out;
  out.name = g.name + " merged";
  out.observer = g.observer;
  out.has_observer = g.has_observer;
  double area = 0;
  for (const auto& n : g.nodes)
    if (n.id == gone) area = n.area;
  for (auto n : g.nodes) {
    if (n.id == gone) continue;
    if (n.id == kept) n.area += area;
    out.nodes.push_back(n);
  }
  for (auto a : g.arcs) {
    if (std::minmax(a.a, a.b) == std::minmax(kept, gone)) continue;
    if (a.a == gone) a.a = kept;
    if (a.b == gone) a.b = kept;
    bool joined = false;
    for (auto& b : out.arcs)
      if (std::minmax(a.a, a.b) == std::minmax(b.a, b.b)) {
        b.border += a.border;
        joined = true;
      }
    if (!joined) out.arcs.push_back(a);
  }
  return out;
}

// The first arc of g between two real faces whose normals are less than max_deg apart: {kept, gone}, the
// larger face kept.
inline std::optional<std::pair<int, int>> shallow_fold(const host::Pfrg& g, double max_deg) {
  for (const auto& a : g.arcs) {
    const host::PfrgNode* x = g.find(a.a);
    const host::PfrgNode* y = g.find(a.b);
    if (!x || !y || x->supernode || y->supernode) continue;
    const double deg = std::acos(std::clamp(x->normal.dot(y->normal), -1.0, 1.0)) * 180.0 / std::numbers::pi;
    if (deg < max_deg) return x->area >= y->area ? std::pair{x->id, y->id} : std::pair{y->id, x->id};
  }
  return std::nullopt;
}

}  // namespace fs::test
