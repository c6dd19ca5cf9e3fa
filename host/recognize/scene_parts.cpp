// Recognizer step 2a: the scene graph a round searches (the whole scene, then what accepted objects leave of
// it) and its connected parts, which the matcher searches one at a time (a solution is connected).
#include <algorithm>

#include "host/match/node_set.hpp"

#include "host/recognize/recognizer_impl.hpp"

namespace fs::host::rec {

using detail::Clock;
using detail::ms_since;

const Pfrg* Recognizer::Impl::split_scene(Recognizer& rz, const Scan& scan, int round, const Vec3& viewpoint,
                                          RecognizeStats& stats) {
  const auto t0 = Clock::now();
  const Pfrg* graph = &rz.scene_;
  if (round == 0) {
    split_components(rz.scene_, scan.min_part, &viewpoint);
    stats.components = static_cast<int>(nparts);
    stats.windows = windows;
    stats.largest_component = largest_component;
    stats.unsearched_faces = unsearched_faces;
  } else {
    if (!scan.small_parts || !build_rest(rz.scene_)) return nullptr;
    graph = &rest;
    split_components(rest, rz.params_.small_part_min_level, &viewpoint);
  }
  round_small = round > 0;
  stats.match_ms += ms_since(t0);
  return graph;
}

void Recognizer::Impl::mark_supernodes(const Pfrg& g) {
  int max_id = 0;
  for (const auto& n : g.nodes) max_id = std::max(max_id, n.id);
  super_by_id.assign(static_cast<std::size_t>(max_id) + 1, 0);
  for (const auto& n : g.nodes)
    if (n.supernode) super_by_id[static_cast<std::size_t>(n.id)] = 1;
}

bool Recognizer::Impl::build_rest(const Pfrg& g) {
  rest.nodes.clear();
  rest.arcs.clear();
  rest.name = g.name;
  rest.observer = g.observer;
  rest.has_observer = g.has_observer;
  int faces = 0, super_id = -1;
  auto kept = [&](int id) {
    return id >= 0 && static_cast<std::size_t>(id) < node_used.size() &&
           !node_used[static_cast<std::size_t>(id)];
  };
  for (const auto& n : g.nodes)
    if (n.supernode || kept(n.id)) {
      rest.nodes.push_back(n);
      faces += n.supernode ? 0 : 1;
      if (n.supernode && super_id < 0) super_id = n.id;
    }
  rest_super_arc.assign(node_used.size(), 0);
  for (const auto& a : g.arcs) {
    const bool sa = is_super(a.a), sb = is_super(a.b);
    if ((sa || kept(a.a)) && (sb || kept(a.b))) {
      rest.arcs.push_back(a);
      if (sa && kept(a.b)) rest_super_arc[static_cast<std::size_t>(a.b)] = 1;
      if (sb && kept(a.a)) rest_super_arc[static_cast<std::size_t>(a.a)] = 1;
    }
  }
  if (super_id >= 0)
    for (const auto& a : g.arcs) {
      const bool ka = kept(a.a), kb = kept(a.b);
      if (ka == kb || is_super(a.a) || is_super(a.b))
        continue;  // both kept, both accepted, or to the supernode
      const int face = ka ? a.a : a.b;
      if (rest_super_arc[static_cast<std::size_t>(face)]) continue;
      rest_super_arc[static_cast<std::size_t>(face)] = 1;
      rest.arcs.push_back(PfrgArc{face, super_id, a.border});
    }
  return faces > 0;
}

int Recognizer::Impl::find(int x) {
  while (uf[static_cast<std::size_t>(x)] != x)
    x = uf[static_cast<std::size_t>(x)] = uf[static_cast<std::size_t>(uf[static_cast<std::size_t>(x)])];
  return x;
}

int Recognizer::Impl::part_cap(const Pfrg& g) const {
  int supers = 0;
  for (const auto& n : g.nodes) supers += n.supernode ? 1 : 0;
  const int cap = match::kMaxNodes - supers;
  return max_part_faces > 0 ? std::min(max_part_faces, cap) : cap;
}

bool Recognizer::Impl::open_part(const Pfrg& g, const Vec3& observer) {
  if (nparts >= kMaxParts) return false;
  const std::size_t k = nparts++;
  part_faces[k] = 0;
  window_part[k] = 0;
  Pfrg& part = parts[k];
  part.nodes.clear();
  part.arcs.clear();
  part.name = g.name;
  part.observer = observer;
  part.has_observer = true;
  for (const auto& sn : g.nodes)
    if (sn.supernode) part.nodes.push_back(sn);
  return true;
}

void Recognizer::Impl::add_part_arcs(const Pfrg& g, std::size_t k, int mark) {
  auto in = [&](int id) { return !is_super(id) && stamp[static_cast<std::size_t>(id)] == mark; };
  for (const auto& a : g.arcs) {
    const bool ia = in(a.a), ib = in(a.b);
    if ((ia && ib) || (ia && is_super(a.b)) || (ib && is_super(a.a))) parts[k].arcs.push_back(a);
  }
}

void Recognizer::Impl::split_windows(const Pfrg& g, int root, int cap, const Vec3& observer) {
  // Faces of the component not yet in a window, in g's order: each starts the next window.
  for (const auto& seed : g.nodes) {
    if (seed.supernode || find(seed.id) != root || part_of[static_cast<std::size_t>(seed.id)] >= 0) continue;
    if (!open_part(g, observer)) {
      for (const auto& n : g.nodes)
        if (!n.supernode && find(n.id) == root && part_of[static_cast<std::size_t>(n.id)] == -1) {
          part_of[static_cast<std::size_t>(n.id)] = -2;
          ++unsearched_faces;
        }
      return;
    }
    const std::size_t k = nparts - 1;
    const int mark = static_cast<int>(k) + 1;
    window_part[k] = 1;
    ++windows;
    // Breadth-first from the seed over face-face arcs, faces already in other windows included (overlap).
    bfs.clear();
    bfs.push_back(seed.id);
    stamp[static_cast<std::size_t>(seed.id)] = mark;
    for (std::size_t head = 0; head < bfs.size() && static_cast<int>(bfs.size()) < cap; ++head) {
      const auto u = static_cast<std::size_t>(bfs[head]);
      for (int e = adj_start[u]; e < adj_start[u + 1] && static_cast<int>(bfs.size()) < cap; ++e) {
        const int v = adj[static_cast<std::size_t>(e)];
        if (stamp[static_cast<std::size_t>(v)] == mark) continue;
        stamp[static_cast<std::size_t>(v)] = mark;
        bfs.push_back(v);
      }
    }
    Pfrg& part = parts[k];
    for (const auto& n : g.nodes)
      if (!n.supernode && stamp[static_cast<std::size_t>(n.id)] == mark) {
        part.nodes.push_back(n);
        ++part_faces[k];
        int& p = part_of[static_cast<std::size_t>(n.id)];
        if (p < 0) p = static_cast<int>(k);
      }
    add_part_arcs(g, k, mark);
  }
}

void Recognizer::Impl::split_components(const Pfrg& g, int min_faces, const Vec3* viewpoint) {
  int max_id = 0;
  for (const auto& n : g.nodes) max_id = std::max(max_id, n.id);
  const auto size = static_cast<std::size_t>(max_id) + 1;
  uf.resize(size);
  for (std::size_t i = 0; i < size; ++i) uf[i] = static_cast<int>(i);
  part_of.assign(size, -1);
  comp_size.assign(size, 0);
  stamp.assign(size, 0);
  adj_start.assign(size + 1, 0);
  for (const auto& a : g.arcs)
    if (!is_super(a.a) && !is_super(a.b)) {
      const int ra = find(a.a), rb = find(a.b);
      if (ra != rb) uf[static_cast<std::size_t>(ra)] = rb;
      ++adj_start[static_cast<std::size_t>(a.a) + 1];
      ++adj_start[static_cast<std::size_t>(a.b) + 1];
    }
  for (std::size_t i = 0; i < size; ++i) adj_start[i + 1] += adj_start[i];
  adj.resize(static_cast<std::size_t>(adj_start[size]));
  {
    // Fill with a moving cursor per node (bfs as scratch), then restore the starts.
    bfs.assign(adj_start.begin(), adj_start.end() - 1);
    for (const auto& a : g.arcs)
      if (!is_super(a.a) && !is_super(a.b)) {
        adj[static_cast<std::size_t>(bfs[static_cast<std::size_t>(a.a)]++)] = a.b;
        adj[static_cast<std::size_t>(bfs[static_cast<std::size_t>(a.b)]++)] = a.a;
      }
  }
  for (const auto& n : g.nodes)
    if (!n.supernode) ++comp_size[static_cast<std::size_t>(find(n.id))];
  // Observer of the whole scene, so that every part sees the same viewing direction.
  Vec3 observer = g.observer;
  if (!g.has_observer) {
    Vec3 sum = Vec3::Zero();
    for (const auto& n : g.nodes)
      if (!n.supernode) sum += n.area * n.normal;
    observer = sum.norm() > 1e-12 ? Vec3(sum.normalized()) : Vec3(Vec3::UnitZ());
  }
  nparts = 0;
  windows = unsearched_faces = largest_component = 0;
  lone_faces.clear();
  for (std::size_t i = 0; i < g.nodes.size(); ++i)
    if (!g.nodes[i].supernode && comp_size[static_cast<std::size_t>(find(g.nodes[i].id))] == 1)
      lone_faces.push_back(static_cast<int>(i));
  const int cap = part_cap(g);
  // Each component within the cap is one part (the components after the last part slot join the last part
  // while it has room); a larger one is covered by windows.
  for (const auto& n : g.nodes) {
    if (n.supernode) continue;
    const int root = find(n.id);
    const int csize = comp_size[static_cast<std::size_t>(root)];
    largest_component = std::max(largest_component, csize);
    if (csize < min_faces) continue;
    if (csize > cap) {
      if (part_of[static_cast<std::size_t>(n.id)] == -1) split_windows(g, root, cap, observer);
      continue;
    }
    int& p = part_of[static_cast<std::size_t>(root)];
    if (p < 0) {
      if (open_part(g, observer)) {
        p = static_cast<int>(nparts) - 1;
      } else if (nparts > 0 && part_faces[nparts - 1] + csize <= cap) {
        p = static_cast<int>(nparts) - 1;
      } else {
        unsearched_faces += csize;
        p = -2;  // the whole component is left out
      }
    }
    if (p == -2) continue;
    part_of[static_cast<std::size_t>(n.id)] = p;
    parts[static_cast<std::size_t>(p)].nodes.push_back(n);
    ++part_faces[static_cast<std::size_t>(p)];
  }
  // Arcs of the parts that are whole components (a window has its arcs already).
  for (std::size_t k = 0; k < nparts; ++k) {
    if (window_part[k]) continue;
    const int mark = static_cast<int>(k) + 1;
    for (const auto& n : parts[k].nodes)
      if (!n.supernode) stamp[static_cast<std::size_t>(n.id)] = -mark;
    add_part_arcs(g, k, -mark);
  }
  if (viewpoint && !g.has_observer)
    for (std::size_t k = 0; k < nparts; ++k) {
      Vec3 c = Vec3::Zero();
      double w = 0.0;
      for (const auto& n : parts[k].nodes)
        if (!n.supernode && n.has_plane) c += n.area * n.centroid, w += n.area;
      if (w <= 0.0) continue;
      const Vec3 d = *viewpoint - c / w;
      if (d.norm() > 1e-9) parts[k].observer = d.normalized();
    }
}

}  // namespace fs::host::rec
