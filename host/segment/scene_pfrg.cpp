#include "host/segment/scene_pfrg.hpp"

#include <algorithm>

namespace fs::host::seg {

ScenePfrgBuilder::ScenePfrgBuilder(std::size_t max_regions, std::size_t max_borders)
    : max_regions_(max_regions), max_borders_(max_borders) {
  arcs_.reserve(max_borders_);
  deg_.resize(max_regions_ + 2);
  off_.resize(max_regions_ + 2);
  adj_.resize(2 * max_borders_ + 2);
}

void ScenePfrgBuilder::prepare(Pfrg& g) const {
  g.nodes.reserve(max_regions_ + 1);
  g.arcs.reserve(max_borders_);
}

void ScenePfrgBuilder::build(const Segmentation& s, Pfrg& g, PreprocessStats* stats) {
  PreprocessStats st;
  const std::int32_t R = std::int32_t(std::min(s.regions.size(), max_regions_));
  const std::int32_t sn = R;  // supernode index in the working graph
  auto known = [&](std::int32_t x) { return x < R && s.regions[std::size_t(x)].known; };

  // 1. complete graph
  arcs_.clear();
  for (const Border& b : s.borders) {
    if (arcs_.size() >= max_borders_ || b.a >= R || b.b >= R) continue;
    if (b.b >= 0 && b.edges < min_border_edges) continue;
    std::int32_t x = b.a, y = b.b < 0 ? sn : b.b;
    if (x > y) std::swap(x, y);
    arcs_.push_back({x, y, b.length, true});
  }
  // adjacency (CSR)
  std::fill(deg_.begin(), deg_.begin() + R + 2, 0);
  for (const WArc& a : arcs_) {
    ++deg_[std::size_t(a.a)];
    ++deg_[std::size_t(a.b)];
  }
  off_[0] = 0;
  for (std::int32_t v = 0; v <= R; ++v)
    off_[std::size_t(v) + 1] = off_[std::size_t(v)] + deg_[std::size_t(v)];
  std::fill(deg_.begin(), deg_.begin() + R + 2, 0);
  for (std::size_t k = 0; k < arcs_.size(); ++k) {
    const WArc& a = arcs_[k];
    adj_[std::size_t(off_[std::size_t(a.a)] + deg_[std::size_t(a.a)]++)] = std::int32_t(k);
    adj_[std::size_t(off_[std::size_t(a.b)] + deg_[std::size_t(a.b)]++)] = std::int32_t(k);
  }
  auto other = [&](const WArc& a, std::int32_t v) { return a.a == v ? a.b : a.a; };
  auto find_arc = [&](std::int32_t u, std::int32_t v) -> WArc* {
    for (std::int32_t k = off_[std::size_t(u)]; k < off_[std::size_t(u) + 1]; ++k) {
      WArc& a = arcs_[std::size_t(adj_[std::size_t(k)])];
      if (a.alive && other(a, u) == v) return &a;
    }
    return nullptr;
  };

  // 2. eliminate border regions
  for (std::int32_t u = 0; u < R; ++u) {
    if (known(u)) {
      ++st.known_regions;
      continue;
    }
    ++st.unknown_regions;
    std::int32_t k1 = -1, k2 = -1;
    double l1 = 0, l2 = 0;
    bool ok = true;
    for (std::int32_t k = off_[std::size_t(u)]; k < off_[std::size_t(u) + 1] && ok; ++k) {
      const WArc& a = arcs_[std::size_t(adj_[std::size_t(k)])];
      if (!a.alive) continue;
      const std::int32_t v = other(a, u);
      if (v == sn) continue;  // its ends may touch the unknown area
      if (!known(v))
        ok = false;
      else if (k1 < 0 || k1 == v) {
        k1 = v;
        l1 += a.len;
      } else if (k2 < 0 || k2 == v) {
        k2 = v;
        l2 += a.len;
      } else
        ok = false;
    }
    if (!ok || k1 < 0 || k2 < 0) continue;
    WArc* ik = find_arc(k1, k2);
    if (ik == nullptr) continue;  // no existing border: could be a jump edge, keep apart
    ik->len += 0.5 * (l1 + l2);
    for (std::int32_t k = off_[std::size_t(u)]; k < off_[std::size_t(u) + 1]; ++k) {
      arcs_[std::size_t(adj_[std::size_t(k)])].alive = false;
    }
    ++st.border_regions_eliminated;
  }

  // 3. eliminate null nodes
  for (std::int32_t u = 0; u < R; ++u) {
    if (known(u)) continue;
    bool touches_sn = false, any = false;
    for (std::int32_t k = off_[std::size_t(u)]; k < off_[std::size_t(u) + 1]; ++k) {
      const WArc& a = arcs_[std::size_t(adj_[std::size_t(k)])];
      if (!a.alive) continue;
      any = true;
      if (other(a, u) == sn) touches_sn = true;
    }
    if (!any) continue;
    for (std::int32_t k = off_[std::size_t(u)]; k < off_[std::size_t(u) + 1]; ++k) {
      WArc& a = arcs_[std::size_t(adj_[std::size_t(k)])];
      if (!a.alive) continue;
      const std::int32_t v = other(a, u);
      if (touches_sn && known(v)) {
        a.a = std::min(v, sn);  // redirect u-v to v-SN (u is part of the unknown area)
        a.b = std::max(v, sn);
      } else {
        a.alive = false;
      }
    }
    ++(touches_sn ? st.null_nodes_to_supernode : st.null_nodes_dropped);
  }

  // 4. merge parallel arcs
  std::size_t m = 0;
  for (const WArc& a : arcs_) {
    if (a.alive && a.a != a.b && (known(a.a) || a.a == sn) && (known(a.b) || a.b == sn)) arcs_[m++] = a;
  }
  arcs_.resize(m);
  st.arcs_before_merge = int(m);
  std::sort(arcs_.begin(), arcs_.end(),
            [](const WArc& x, const WArc& y) { return x.a != y.a ? x.a < y.a : x.b < y.b; });

  g.nodes.clear();
  g.arcs.clear();
  auto node_id = [&](std::int32_t x) { return x == sn ? 0 : int(x) + 1; };
  PfrgNode super;
  super.id = 0;
  super.supernode = true;
  g.nodes.push_back(super);
  for (std::int32_t r = 0; r < R; ++r) {
    if (!known(r)) continue;
    const Region& reg = s.regions[std::size_t(r)];
    PfrgNode nd;
    nd.id = node_id(r);
    nd.area = reg.area;
    nd.normal = reg.plane.n;
    nd.offset = reg.plane.d;
    nd.centroid = reg.centroid;
    nd.has_plane = true;
    g.nodes.push_back(nd);
  }
  for (std::size_t k = 0; k < arcs_.size(); ++k) {
    const WArc& a = arcs_[k];
    PfrgArc arc;
    arc.a = std::min(node_id(a.a), node_id(a.b));
    arc.b = std::max(node_id(a.a), node_id(a.b));
    arc.border = a.len;
    if (!g.arcs.empty() && g.arcs.back().a == arc.a && g.arcs.back().b == arc.b) {
      g.arcs.back().border += a.len;
      continue;
    }
    g.arcs.push_back(arc);
  }
  st.arcs = int(g.arcs.size());
  if (stats) *stats = st;
}

}  // namespace fs::host::seg
