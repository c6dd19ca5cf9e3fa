// ArcIndex: reference arcs by angle and area (see arc_index.hpp for why skipping is exact).
#include "host/match/arc_index.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <numbers>
#include <tuple>

#include <fmt/format.h>

#include "common/error.hpp"

namespace fs::host::match {

namespace {

// Float storage and the matcher's cosine form of the rigidity test round differently: the index accepts this
// much more so that it never removes what the matcher keeps.
constexpr double kAngleSlackDeg = 1e-3;
constexpr double kAreaSlackRel = 1e-6;
// Scene parts the path check takes (a larger one is checked by its arcs only).
constexpr std::size_t kMaxPathNodes = 256, kMaxPathArcs = 4096, kMaxPaths = 16384;

double angle_deg(const Vec3& a, const Vec3& b) {
  return std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

bool area_rule(const MatchParams& p) {
  return p.on(Condition::kNodeSimilarity) && std::isfinite(p.th_area_ratio) && p.th_area_ratio > 0 &&
         p.th_area_fold_deg <= kAreaFoldMaxDeg;  // (false for NaN too)
}

bool angle_rule(const MatchParams& p) {
  return p.on(Condition::kRigidity) && p.rigidity_pairs && p.th_omega_deg < 180.0;
}

// The smallest reference area a scene face of area a_s can be matched to (one-sided area condition).
double min_ref_area(const MatchParams& p, double a_s) {
  if (!area_rule(p)) return -1.0;
  return (a_s - p.th_area_slack_mm2) / p.th_area_ratio * (1.0 - kAreaSlackRel) - kAreaSlackRel;
}

}  // namespace

ArcIndex::Scratch::Scratch() {
  adj_start.reserve(kMaxPathNodes + 1);
  cursor.reserve(kMaxPathNodes + 1);
  adj.reserve(2 * kMaxPathArcs);
  paths.reserve(kMaxPaths);
}

// Reference g: its arcs in both directions (entries_, sorted later) and its paths x - y - z, one signature
// per distinct triple of angles with the largest areas.
void ArcIndex::add_reference(const Pfrg& g, std::uint32_t ref) {
  const std::size_t first = paths_.size();
  float flattest = 90.0f;
  auto index_of = [&](int id) {
    for (std::size_t i = 0; i < g.nodes.size(); ++i)
      if (g.nodes[i].id == id) return g.nodes[i].supernode ? -1 : static_cast<int>(i);
    return -1;
  };
  // The arcs between real faces, resolved once: node indexes and the angle between their normals.
  struct Arc {
    std::size_t a, b;
    float angle;
  };
  std::vector<Arc> arcs;
  arcs.reserve(g.arcs.size());
  std::vector<std::vector<int>> adj(g.nodes.size());
  for (const PfrgArc& arc : g.arcs) {
    const int a = index_of(arc.a), b = index_of(arc.b);
    if (a < 0 || b < 0) continue;
    adj[static_cast<std::size_t>(a)].push_back(b);
    adj[static_cast<std::size_t>(b)].push_back(a);
    const auto ua = static_cast<std::size_t>(a), ub = static_cast<std::size_t>(b);
    arcs.push_back({ua, ub, static_cast<float>(angle_deg(g.nodes[ua].normal, g.nodes[ub].normal))});
  }
  // The areas the matcher's area condition may compare with: each face with its neighbours across folds of up
  // to kAreaFoldMaxDeg (MatchParams::th_area_fold_deg is at most that).
  std::vector<double> folded(g.nodes.size());
  for (std::size_t i = 0; i < g.nodes.size(); ++i) folded[i] = g.nodes[i].area;
  for (const Arc& arc : arcs)
    if (arc.angle < kAreaFoldMaxDeg + kAngleSlackDeg) {
      folded[arc.a] += g.nodes[arc.b].area;
      folded[arc.b] += g.nodes[arc.a].area;
    }
  std::vector<float> area(folded.begin(), folded.end());
  for (const Arc& arc : arcs) {
    flattest = std::min(flattest, std::min(arc.angle, 180.0f - arc.angle));
    entries_.push_back({arc.angle, area[arc.a], area[arc.b], ref});
    entries_.push_back({arc.angle, area[arc.b], area[arc.a], ref});
  }
  for (std::size_t y = 0; y < g.nodes.size(); ++y) {
    const PfrgNode& ny = g.nodes[y];
    for (int x : adj[y]) {
      const PfrgNode& nx = g.nodes[static_cast<std::size_t>(x)];
      for (int z : adj[y]) {
        if (z == x) continue;
        const PfrgNode& nz = g.nodes[static_cast<std::size_t>(z)];
        paths_.push_back({static_cast<float>(angle_deg(nx.normal, ny.normal)),
                          static_cast<float>(angle_deg(ny.normal, nz.normal)),
                          static_cast<float>(angle_deg(nx.normal, nz.normal)),
                          area[static_cast<std::size_t>(x)], area[y], area[static_cast<std::size_t>(z)]});
      }
    }
  }
  const auto begin = paths_.begin() + static_cast<std::ptrdiff_t>(first);
  std::sort(begin, paths_.end(), [](const PathSig& p, const PathSig& q) {
    return std::tie(p.xy, p.yz, p.xz) < std::tie(q.xy, q.yz, q.xz);
  });
  std::size_t kept = first;
  for (std::size_t i = first; i < paths_.size(); ++i) {
    const PathSig p = paths_[i];
    if (kept > first) {
      PathSig& last = paths_[kept - 1];
      if (last.xy == p.xy && last.yz == p.yz && last.xz == p.xz) {
        last.ax = std::max(last.ax, p.ax);  // the largest of each: passes wherever one of them passes
        last.ay = std::max(last.ay, p.ay);
        last.az = std::max(last.az, p.az);
        continue;
      }
    }
    paths_[kept++] = p;
  }
  paths_.resize(kept);
  path_start_[ref + 1] = static_cast<std::uint32_t>(kept);
  flattest_[ref] = flattest;
}

ArcIndex::ArcIndex(std::span<const Pfrg* const> references) : references_(references.size()) {
  path_start_.assign(references.size() + 1, 0);
  flattest_.assign(references.size(), 90.0f);
  fingerprints_.resize(references.size());
  for (std::size_t k = 0; k < references.size(); ++k) {
    add_reference(*references[k], static_cast<std::uint32_t>(k));
    fingerprints_[k] = fingerprint(*references[k]);
  }
  // Within one reference and one angle, an arc whose two areas are both at most another's passes only where
  // that one passes too: keep the undominated ones.
  std::sort(entries_.begin(), entries_.end(), [&](const Entry& x, const Entry& y) {
    if (x.ref != y.ref) return x.ref < y.ref;
    if (x.angle != y.angle) return x.angle < y.angle;
    if (x.a0 != y.a0) return x.a0 > y.a0;
    return x.a1 > y.a1;
  });
  std::size_t kept = 0;
  float best_a1 = 0;
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    const Entry& e = entries_[i];
    const bool same = kept > 0 && entries_[kept - 1].ref == e.ref && entries_[kept - 1].angle == e.angle;
    if (same && e.a1 <= best_a1) continue;
    best_a1 = same ? std::max(best_a1, e.a1) : e.a1;
    entries_[kept++] = e;
  }
  entries_.resize(kept);
  entries_.shrink_to_fit();
  paths_.shrink_to_fit();
  sort_entries();
}

namespace {

int bucket_of(float angle, int buckets) { return std::clamp(static_cast<int>(angle), 0, buckets - 1); }

bool entry_before(const ArcIndex::Entry& x, const ArcIndex::Entry& y, int buckets) {
  const int bx = bucket_of(x.angle, buckets), by = bucket_of(y.angle, buckets);
  if (bx != by) return bx < by;
  if (x.a0 != y.a0) return x.a0 > y.a0;
  // The rest only makes the order total, so that an index has one byte image however it was put together.
  return std::tie(x.ref, x.angle, x.a1) < std::tie(y.ref, y.angle, y.a1);
}

}  // namespace

void ArcIndex::sort_entries() {
  std::sort(entries_.begin(), entries_.end(),
            [](const Entry& x, const Entry& y) { return entry_before(x, y, kBuckets); });
  count_buckets();
}

void ArcIndex::count_buckets() {
  start_.fill(0);
  for (const Entry& e : entries_) ++start_[static_cast<std::size_t>(bucket_of(e.angle, kBuckets)) + 1];
  for (int b = 0; b < kBuckets; ++b)
    start_[static_cast<std::size_t>(b) + 1] += start_[static_cast<std::size_t>(b)];
}

ArcIndex ArcIndex::concat(std::span<const ArcIndex* const> parts) {
  ArcIndex out;
  std::size_t entries = 0, paths = 0;
  for (const ArcIndex* part : parts) {
    out.references_ += part->references_;
    entries += part->entries_.size();
    paths += part->paths_.size();
  }
  out.entries_.reserve(entries);
  out.paths_.reserve(paths);
  out.path_start_.reserve(out.references_ + 1);  // holds the first start, 0
  out.flattest_.reserve(out.references_);
  out.fingerprints_.reserve(out.references_);
  std::uint32_t base = 0;
  for (const ArcIndex* part : parts) {
    for (Entry e : part->entries_) {
      e.ref += base;
      out.entries_.push_back(e);
    }
    const auto path_base = static_cast<std::uint32_t>(out.paths_.size());
    out.paths_.insert(out.paths_.end(), part->paths_.begin(), part->paths_.end());
    for (std::size_t k = 1; k < part->path_start_.size(); ++k)
      out.path_start_.push_back(path_base + part->path_start_[k]);
    out.flattest_.insert(out.flattest_.end(), part->flattest_.begin(), part->flattest_.end());
    out.fingerprints_.insert(out.fingerprints_.end(), part->fingerprints_.begin(), part->fingerprints_.end());
    base += static_cast<std::uint32_t>(part->references_);
  }
  out.sort_entries();
  return out;
}

ArcIndex ArcIndex::from_arrays(std::size_t references, std::vector<Entry> entries, std::vector<PathSig> paths,
                               std::vector<std::uint32_t> path_start, std::vector<float> flattest,
                               std::vector<std::uint32_t> fingerprints) {
  auto angle_ok = [](float a) { return std::isfinite(a) && a >= 0.0f && a <= 180.0f; };
  auto area_ok = [](float a) { return std::isfinite(a) && a >= 0.0f; };
  if (path_start.size() != references + 1 || flattest.size() != references ||
      fingerprints.size() != references)
    throw Error(
        fmt::format("arc index: {} path starts, {} flattest angles, {} fingerprints for {} references",
                    path_start.size(), flattest.size(), fingerprints.size(), references));
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const Entry& e = entries[i];
    if (e.ref >= references || !angle_ok(e.angle) || !area_ok(e.a0) || !area_ok(e.a1))
      throw Error(fmt::format("arc index: entry {} (reference {}, angle {}, areas {} {}) out of range", i,
                              e.ref, e.angle, e.a0, e.a1));
    if (i > 0 && entry_before(e, entries[i - 1], kBuckets))
      throw Error(fmt::format("arc index: entry {} is out of order", i));
  }
  if (path_start[0] != 0 || path_start[references] != paths.size())
    throw Error(fmt::format("arc index: path starts run from {} to {}, not 0 to {}", path_start[0],
                            path_start[references], paths.size()));
  // Every start within the paths before any is used (a middle one may not point past the end).
  for (std::size_t k = 0; k < references; ++k)
    if (path_start[k + 1] < path_start[k] || path_start[k + 1] > paths.size())
      throw Error(fmt::format("arc index: path start {} of reference {} is not between {} and {}",
                              path_start[k + 1], k + 1, path_start[k], paths.size()));
  for (std::size_t k = 0; k < references; ++k) {
    if (!(flattest[k] >= 0.0f && flattest[k] <= 90.0f))
      throw Error(fmt::format("arc index: flattest angle {} of reference {} out of range", flattest[k], k));
    for (std::uint32_t i = path_start[k]; i < path_start[k + 1]; ++i) {
      const PathSig& g = paths[i];
      if (!angle_ok(g.xy) || !angle_ok(g.yz) || !angle_ok(g.xz) || !area_ok(g.ax) || !area_ok(g.ay) ||
          !area_ok(g.az))
        throw Error(fmt::format("arc index: path {} of reference {} out of range", i, k));
      if (i > path_start[k] && g.xy < paths[i - 1].xy)
        throw Error(fmt::format("arc index: path {} of reference {} is out of order", i, k));
    }
  }
  ArcIndex out;
  out.references_ = references;
  out.entries_ = std::move(entries);
  out.paths_ = std::move(paths);
  out.path_start_ = std::move(path_start);
  out.flattest_ = std::move(flattest);
  out.fingerprints_ = std::move(fingerprints);
  out.count_buckets();
  return out;
}

std::uint32_t ArcIndex::fingerprint(const Pfrg& g) {
  std::uint64_t h = 0x9E3779B97F4A7C15ull;
  auto mix = [&h](std::uint64_t v) {  // one multiply-xorshift round per word
    h = (h ^ v) * 0xBF58476D1CE4E5B9ull;
    h ^= h >> 31;
  };
  auto node = [&](int id) {  // a model's node id is its index
    const auto i = static_cast<std::size_t>(id);
    return id >= 0 && i < g.nodes.size() && g.nodes[i].id == id ? &g.nodes[i] : g.find(id);
  };
  for (const PfrgNode& n : g.nodes) {
    if (n.supernode) continue;
    mix(static_cast<std::uint64_t>(static_cast<std::uint32_t>(n.id)));
    mix(std::bit_cast<std::uint64_t>(n.area));
    for (int i = 0; i < 3; ++i) mix(std::bit_cast<std::uint64_t>(n.normal[i]));
  }
  for (const PfrgArc& arc : g.arcs) {
    const PfrgNode* a = node(arc.a);
    const PfrgNode* b = node(arc.b);
    if (!a || !b || a->supernode || b->supernode) continue;
    mix(static_cast<std::uint64_t>(static_cast<std::uint32_t>(arc.a)) << 32 |
        static_cast<std::uint32_t>(arc.b));
  }
  return static_cast<std::uint32_t>(h ^ (h >> 32));
}

bool ArcIndex::describes(std::span<const Pfrg* const> references) const {
  if (references.size() != references_) return false;
  for (std::size_t k = 0; k < references.size(); ++k)
    if (fingerprint(*references[k]) != fingerprints_[k]) return false;
  return true;
}

bool ArcIndex::applies(const MatchParams& p) {
  return p.on(Condition::kConnectivity) && p.on(Condition::kNeighborMatch) && p.th_minlevel >= 2;
}

namespace {

// scratch.paths = the paths x - y - z of the scene's real faces; false when the part is too large for it.
bool scene_paths(const Pfrg& scene, const MatchParams& p, ArcIndex::Scratch& sc) {
  const std::size_t n = scene.nodes.size();
  if (n > kMaxPathNodes || scene.arcs.size() > kMaxPathArcs) return false;
  auto index_of = [&](int id) {
    for (std::size_t i = 0; i < n; ++i)
      if (scene.nodes[i].id == id) return scene.nodes[i].supernode ? -1 : static_cast<int>(i);
    return -1;
  };
  sc.adj_start.assign(n + 1, 0);
  for (const PfrgArc& arc : scene.arcs) {
    const int a = index_of(arc.a), b = index_of(arc.b);
    if (a < 0 || b < 0) continue;
    ++sc.adj_start[static_cast<std::size_t>(a) + 1];
    ++sc.adj_start[static_cast<std::size_t>(b) + 1];
  }
  for (std::size_t i = 0; i < n; ++i) sc.adj_start[i + 1] += sc.adj_start[i];
  sc.cursor.assign(sc.adj_start.begin(), sc.adj_start.end());
  sc.adj.assign(static_cast<std::size_t>(sc.adj_start[n]), 0);
  for (const PfrgArc& arc : scene.arcs) {
    const int a = index_of(arc.a), b = index_of(arc.b);
    if (a < 0 || b < 0) continue;
    sc.adj[static_cast<std::size_t>(sc.cursor[static_cast<std::size_t>(a)]++)] = b;
    sc.adj[static_cast<std::size_t>(sc.cursor[static_cast<std::size_t>(b)]++)] = a;
  }
  sc.paths.clear();
  for (std::size_t y = 0; y < n; ++y) {
    const PfrgNode& ny = scene.nodes[y];
    const auto lo = static_cast<std::size_t>(sc.adj_start[y]),
               hi = static_cast<std::size_t>(sc.adj_start[y + 1]);
    for (std::size_t i = lo; i < hi; ++i) {
      const PfrgNode& nx = scene.nodes[static_cast<std::size_t>(sc.adj[i])];
      for (std::size_t j = lo; j < hi; ++j) {
        if (j == i) continue;
        if (sc.paths.size() == kMaxPaths) return false;
        const PfrgNode& nz = scene.nodes[static_cast<std::size_t>(sc.adj[j])];
        sc.paths.push_back({static_cast<float>(angle_deg(nx.normal, ny.normal)),
                            static_cast<float>(angle_deg(ny.normal, nz.normal)),
                            static_cast<float>(angle_deg(nx.normal, nz.normal)),
                            static_cast<float>(min_ref_area(p, nx.area)),
                            static_cast<float>(min_ref_area(p, ny.area)),
                            static_cast<float>(min_ref_area(p, nz.area))});
      }
    }
  }
  return true;
}

}  // namespace

// Some path of the scene has a path of reference `ref` that passes (arc_index.hpp): its first arc within
// omega, the two other angles within omega + that arc's difference, every face large enough. Every difference
// is then at most 2 omega, so the x - y angles (sorted) are searched in that window only.
bool ArcIndex::path_passes(const Scratch& sc, std::size_t ref, double omega) const {
  const auto first = paths_.begin() + path_start_[ref], last = paths_.begin() + path_start_[ref + 1];
  for (const Scratch::Path& sp : sc.paths) {
    auto it = std::lower_bound(first, last, static_cast<float>(sp.xy - 2.0 * omega),
                               [](const PathSig& g, float v) { return g.xy < v; });
    for (; it != last && it->xy <= sp.xy + 2.0 * omega; ++it) {
      const PathSig& g = *it;
      if (g.ax < sp.need_x || g.ay < sp.need_y || g.az < sp.need_z) continue;
      const double dxy = std::abs(double(g.xy) - sp.xy), dyz = std::abs(double(g.yz) - sp.yz),
                   dxz = std::abs(double(g.xz) - sp.xz);
      if ((dxy <= omega && dyz <= omega + dxy && dxz <= omega + dxy) ||
          (dyz <= omega && dxy <= omega + dyz && dxz <= omega + dyz))
        return true;
    }
  }
  return false;
}

void ArcIndex::candidates(const Pfrg& scene, const MatchParams& p, std::span<std::uint64_t> mark,
                          std::uint64_t bit, Scratch& scratch) const {
  const std::size_t n = std::min(mark.size(), references_);
  if (!applies(p)) {
    for (std::size_t k = 0; k < n; ++k) mark[k] |= bit;
    return;
  }
  const bool by_angle = angle_rule(p);
  const double omega = by_angle ? p.th_omega_deg + kAngleSlackDeg : 180.0;
  for (const PfrgArc& arc : scene.arcs) {
    const PfrgNode* a = scene.find(arc.a);
    const PfrgNode* b = scene.find(arc.b);
    if (!a || !b || a->supernode || b->supernode) continue;
    const double angle = angle_deg(a->normal, b->normal);
    const double need0 = min_ref_area(p, a->area), need1 = min_ref_area(p, b->area);
    const int lo = std::max(0, static_cast<int>(std::floor(angle - omega)));
    const int hi = std::min(kBuckets - 1, static_cast<int>(std::floor(angle + omega)));
    for (int bk = lo; bk <= hi; ++bk) {
      const auto end = start_[static_cast<std::size_t>(bk) + 1];
      for (auto i = start_[static_cast<std::size_t>(bk)]; i < end; ++i) {
        const Entry& e = entries_[i];
        if (e.a0 < need0) break;  // a0 descending: none further passes
        if (e.ref >= n || (mark[e.ref] & bit) || e.a1 < need1) continue;
        if (std::abs(static_cast<double>(e.angle) - angle) <= omega) mark[e.ref] |= bit;
      }
    }
  }
  // Level 3 (TH_minlevel >= 3, rigidity from the two-pair fit): the paths.
  if (!(by_angle && p.th_minlevel >= 3 && p.on(Condition::kRigidity)) || !scene_paths(scene, p, scratch))
    return;
  for (std::size_t k = 0; k < n; ++k) {
    if (!(mark[k] & bit)) continue;
    // A first pair within the degenerate angle of parallel has no rotation fit: not checked.
    if (static_cast<double>(flattest_[k]) <= p.degenerate_deg + kAngleSlackDeg) continue;
    if (!path_passes(scratch, k, omega)) mark[k] &= ~bit;
  }
}

}  // namespace fs::host::match
