#include "host/match/ullmann.hpp"

#include <memory>
#include <vector>

#include "host/match/compact_graph.hpp"

namespace fs::host::match {

namespace {

class Ullmann {
 public:
  Ullmann(const CompactGraph& t, const CompactGraph& r, ExactMode mode, const ExactMappingFn& fn)
      : t_(t),
        r_(r),
        mode_(mode),
        fn_(fn),
        levels_(static_cast<std::size_t>(t.n) + 1),
        assigned_(static_cast<std::size_t>(t.n), -1),
        pairs_(static_cast<std::size_t>(t.n)) {}

  ExactStats run() {
    if (t_.n == 0 || t_.n > r_.n) return stats_;
    auto& m0 = levels_[0];
    for (int i = 0; i < t_.n; ++i) {
      m0[i] = NodeSet{};
      for (int j = 0; j < r_.n; ++j) {
        // Node-degree condition (ch. 5.3.2.2): equal for graphs of equal size, <= otherwise.
        const bool ok = (t_.n == r_.n && mode_ == ExactMode::kInduced) ? t_.degree[i] == r_.degree[j]
                                                                       : t_.degree[i] <= r_.degree[j];
        if (ok) m0[i].set(j);
      }
    }
    if (refine(m0, 0)) search(0, NodeSet{});
    return stats_;
  }

 private:
  using Matrix = std::array<NodeSet, kMaxNodes>;

  // Structural refinement: (t_i, r_j) stays possible only if every neighbour t_x of t_i can still be matched
  // with some neighbour of r_j. Repeats until stable. Returns false when a row of an unassigned node empties.
  bool refine(Matrix& m, int depth) {
    bool changed = true;
    while (changed) {
      changed = false;
      for (int i = depth; i < t_.n; ++i) {
        NodeSet row = m[i];
        row.for_each([&](int j) {
          bool ok = true;
          t_.adj[i].for_each([&](int x) {
            if (ok && !(m[x] & r_.adj[j]).any()) ok = false;
          });
          if (!ok) {
            m[i].reset(j);
            ++stats_.refinement_removals;
            changed = true;
          }
        });
        if (!m[i].any()) return false;
      }
    }
    return true;
  }

  bool consistent(int d, int j) const {
    // Against the nodes already assigned (backward check): arcs must agree (induced) or be present (mono).
    for (int x = 0; x < d; ++x) {
      const bool ta = t_.adj[d].test(x);
      const bool ra = r_.adj[j].test(assigned_[static_cast<std::size_t>(x)]);
      if (ta && !ra) return false;
      if (mode_ == ExactMode::kInduced && !ta && ra) return false;
    }
    return true;
  }

  void search(int d, NodeSet used) {
    ++stats_.tree_nodes;
    if (d == t_.n) {
      ++stats_.count;
      if (fn_) {
        for (int i = 0; i < t_.n; ++i)
          pairs_[static_cast<std::size_t>(i)] = {t_.id[i], r_.id[assigned_[static_cast<std::size_t>(i)]]};
        fn_(pairs_);
      }
      return;
    }
    const Matrix& m = levels_[static_cast<std::size_t>(d)];
    NodeSet cand = m[d].minus(used);
    cand.for_each([&](int j) {
      if (!consistent(d, j)) return;
      Matrix& next = levels_[static_cast<std::size_t>(d) + 1];
      next = m;
      next[d] = NodeSet{};
      next[d].set(j);
      for (int i = d + 1; i < t_.n; ++i) next[i].reset(j);
      assigned_[static_cast<std::size_t>(d)] = j;
      NodeSet u = used;
      u.set(j);
      if (refine(next, d + 1)) search(d + 1, u);
      assigned_[static_cast<std::size_t>(d)] = -1;
    });
  }

  const CompactGraph& t_;
  const CompactGraph& r_;
  ExactMode mode_;
  const ExactMappingFn& fn_;
  std::vector<Matrix> levels_;
  std::vector<int> assigned_;
  std::vector<std::pair<int, int>> pairs_;
  ExactStats stats_;
};

}  // namespace

ExactStats count_isomorphisms(const Pfrg& test, const Pfrg& ref, ExactMode mode,
                              const ExactMappingFn& on_mapping) {
  auto t = std::make_unique<CompactGraph>();
  auto r = std::make_unique<CompactGraph>();
  t->load(test, /*include_supernodes=*/false);
  r->load(ref, /*include_supernodes=*/false);
  return Ullmann(*t, *r, mode, on_mapping).run();
}

}  // namespace fs::host::match
