#include "host/match/compact_graph.hpp"

#include <cmath>
#include <numbers>
#include <string>

#include "common/error.hpp"

namespace fs::host::match {

void CompactGraph::load(const Pfrg& g, bool include_supernodes) {
  int count = 0;
  for (const auto& node : g.nodes)
    if (include_supernodes || !node.supernode) ++count;
  if (count > kMaxNodes)
    throw Error((g.name.empty() ? std::string("graph") : g.name) + ": " + std::to_string(count) +
                " nodes, the matcher handles at most " + std::to_string(kMaxNodes));
  for (int i = 0; i < n; ++i) {
    adj[i] = NodeSet{};
    for (int k = 0; k < n; ++k) border[i][k] = 0.0F;
  }
  n = 0;
  real = NodeSet{};
  for (const auto& node : g.nodes) {
    if (!include_supernodes && node.supernode) continue;
    id[n] = node.id;
    supernode[n] = node.supernode;
    area[n] = node.supernode ? 0.0 : node.area;
    normal[n] = node.supernode ? Vec3::Zero() : node.normal;
    degree[n] = 0;
    adj[n] = NodeSet{};
    for (int k = 0; k < count; ++k) border[n][k] = 0.0F;
    if (!node.supernode) real.set(n);
    ++n;
  }
  for (const auto& a : g.arcs) {
    const int i = index_of(a.a), k = index_of(a.b);
    if (i < 0 || k < 0) {
      if (!include_supernodes && (g.find(a.a) != nullptr && g.find(a.b) != nullptr))
        continue;  // supernode arc
      throw Error((g.name.empty() ? std::string("graph") : g.name) + ": arc " + std::to_string(a.a) + "-" +
                  std::to_string(a.b) + " names an unknown node");
    }
    if (i == k || adj[i].test(k)) continue;
    adj[i].set(k);
    adj[k].set(i);
    border[i][k] = border[k][i] = static_cast<float>(a.border);
    ++degree[i];
    ++degree[k];
  }
  // Observer: given, else the area-weighted mean of the face normals (all visible faces face the sensor).
  if (g.has_observer) {
    observer = g.observer;
  } else {
    Vec3 s = Vec3::Zero();
    for (int i = 0; i < n; ++i)
      if (!supernode[i]) s += area[i] * normal[i];
    observer = s.norm() > 1e-12 ? Vec3(s.normalized()) : Vec3(Vec3::UnitZ());
  }
}

double area_with_shallow_folds(const CompactGraph& g, int i, double fold_deg) {
  const auto ui = static_cast<std::size_t>(i);
  double a = g.area[ui];
  if (fold_deg <= 0 || g.supernode[ui]) return a;
  const double c = std::cos(fold_deg * std::numbers::pi / 180.0);
  for (int k = 0; k < g.n; ++k)
    if (g.adj[ui].test(k) && g.real.test(k) && g.normal[ui].dot(g.normal[static_cast<std::size_t>(k)]) > c)
      a += g.area[static_cast<std::size_t>(k)];
  return a;
}

int CompactGraph::index_of(int node_id) const {
  for (int i = 0; i < n; ++i)
    if (id[i] == node_id) return i;
  return -1;
}

}  // namespace fs::host::match
