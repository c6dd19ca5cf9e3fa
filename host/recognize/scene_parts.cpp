// Recognizer step 2a: the scene graph a round searches (the whole scene, then what accepted objects leave of
// it) and its connected parts, which the matcher searches one at a time (a solution is connected).
#include <algorithm>

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

void Recognizer::Impl::split_components(const Pfrg& g, int min_faces, const Vec3* viewpoint) {
  int max_id = 0;
  for (const auto& n : g.nodes) max_id = std::max(max_id, n.id);
  const auto size = static_cast<std::size_t>(max_id) + 1;
  uf.resize(size);
  for (std::size_t i = 0; i < size; ++i) uf[i] = static_cast<int>(i);
  part_of.assign(size, -1);
  comp_size.assign(size, 0);
  for (const auto& a : g.arcs)
    if (!is_super(a.a) && !is_super(a.b)) {
      const int ra = find(a.a), rb = find(a.b);
      if (ra != rb) uf[static_cast<std::size_t>(ra)] = rb;
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
  lone_faces.clear();
  for (std::size_t i = 0; i < g.nodes.size(); ++i)
    if (!g.nodes[i].supernode && comp_size[static_cast<std::size_t>(find(g.nodes[i].id))] == 1)
      lone_faces.push_back(static_cast<int>(i));
  for (const auto& n : g.nodes) {
    if (n.supernode) continue;
    const int root = find(n.id);
    if (comp_size[static_cast<std::size_t>(root)] < min_faces) continue;
    int& p = part_of[static_cast<std::size_t>(root)];
    if (p < 0) {
      if (nparts < kMaxParts) {
        p = static_cast<int>(nparts++);
        part_faces[static_cast<std::size_t>(p)] = 0;
        Pfrg& part = parts[static_cast<std::size_t>(p)];
        part.nodes.clear();
        part.arcs.clear();
        part.name = g.name;
        part.observer = observer;
        part.has_observer = true;
        for (const auto& sn : g.nodes)
          if (sn.supernode) part.nodes.push_back(sn);
      } else {
        p = static_cast<int>(kMaxParts) - 1;
      }
    }
    part_of[static_cast<std::size_t>(n.id)] = p;
    parts[static_cast<std::size_t>(p)].nodes.push_back(n);
    ++part_faces[static_cast<std::size_t>(p)];
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
  for (const auto& a : g.arcs) {
    const bool sa = is_super(a.a), sb = is_super(a.b);
    const int pa = sa ? -1 : part_of[static_cast<std::size_t>(a.a)];
    const int pb = sb ? -1 : part_of[static_cast<std::size_t>(a.b)];
    const int p = pa >= 0 ? pa : pb;
    if (p < 0 || (pa >= 0 && pb >= 0 && pa != pb)) continue;
    parts[static_cast<std::size_t>(p)].arcs.push_back(a);
  }
}

}  // namespace fs::host::rec
