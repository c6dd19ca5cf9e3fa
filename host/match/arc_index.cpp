// ArcIndex: reference arcs by angle and area (see arc_index.hpp for why skipping is exact).
#include "host/match/arc_index.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace fs::host::match {

namespace {

// Float storage and the matcher's cosine form of the rigidity test round differently: the index accepts this
// much more so that it never removes what the matcher keeps.
constexpr double kAngleSlackDeg = 1e-3;
constexpr double kAreaSlackRel = 1e-6;

double angle_deg(const Vec3& a, const Vec3& b) {
  return std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

bool area_rule(const MatchParams& p) {
  return p.on(Condition::kNodeSimilarity) && std::isfinite(p.th_area_ratio) && p.th_area_ratio > 0;
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

ArcIndex::ArcIndex(std::span<const Pfrg* const> references) : references_(references.size()) {
  for (std::size_t k = 0; k < references.size(); ++k) {
    const Pfrg& g = *references[k];
    for (const PfrgArc& arc : g.arcs) {
      const PfrgNode* a = g.find(arc.a);
      const PfrgNode* b = g.find(arc.b);
      if (!a || !b || a->supernode || b->supernode) continue;  // never matched
      const auto angle = static_cast<float>(angle_deg(a->normal, b->normal));
      const auto ref = static_cast<std::uint32_t>(k);
      entries_.push_back({angle, static_cast<float>(a->area), static_cast<float>(b->area), ref});
      entries_.push_back({angle, static_cast<float>(b->area), static_cast<float>(a->area), ref});
    }
  }
  auto bucket = [](const Entry& e) { return std::clamp(static_cast<int>(e.angle), 0, kBuckets - 1); };
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
  std::sort(entries_.begin(), entries_.end(), [&](const Entry& x, const Entry& y) {
    if (bucket(x) != bucket(y)) return bucket(x) < bucket(y);
    if (x.a0 != y.a0) return x.a0 > y.a0;
    return x.ref < y.ref;
  });
  start_.fill(0);
  for (const Entry& e : entries_) ++start_[static_cast<std::size_t>(bucket(e)) + 1];
  for (int b = 0; b < kBuckets; ++b)
    start_[static_cast<std::size_t>(b) + 1] += start_[static_cast<std::size_t>(b)];
}

bool ArcIndex::applies(const MatchParams& p) {
  return p.on(Condition::kConnectivity) && p.on(Condition::kNeighborMatch) && p.th_minlevel >= 2;
}

void ArcIndex::candidates(const Pfrg& scene, const MatchParams& p, std::span<std::uint64_t> mark,
                          std::uint64_t bit) const {
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
}

}  // namespace fs::host::match
