// Solutions of the inexact matcher (thesis ch. 7.7): leaf states of level >= TH_minlevel and, after a global
// stop, the unexpanded states (incomplete solutions); the subset condition; ranked by cost (+ zeta U,
// params.hpp) and copied into the reported Solution list.
#include <algorithm>
#include <array>
#include <limits>

#include "host/match/inexact_impl.hpp"

namespace fs::host::match {

namespace {

// U of the zeta ranking (params.hpp), two sides, each the area share of the real faces adjacent to a
// match's faces that it leaves unmatched, weighted by face_weight(i) in [0, 1]: the open area over that
// plus the matched area of graph g for the core set `core`.
template <class Weight>
double open_neighbour_share(const CompactGraph& g, const NodeSet& core, Weight face_weight) {
  NodeSet around;
  double matched = 0.0;
  core.for_each([&](int i) {
    around = around | g.adj[static_cast<std::size_t>(i)];
    matched += g.area[static_cast<std::size_t>(i)];
  });
  double open = 0.0;
  (around & g.real).minus(core).for_each([&](int i) {
    open += face_weight(i) * g.area[static_cast<std::size_t>(i)];
  });
  return open + matched > 0.0 ? open / (open + matched) : 0.0;
}

}  // namespace

void InexactMatcher::Impl::collect(MatchStats& st) {
  gather_leaves(st);
  order_leaves();
  subset_condition(st);
  const std::size_t n = rank_solutions(std::min(leaves.size(), solutions.size()));
  fill_solutions(n);
  set_result_stats(n, st);
}

// The solution candidates: expanded states without children (complete) and, after a global stop, the open
// states (incomplete, 7.7.3).
void InexactMatcher::Impl::gather_leaves(MatchStats& st) {
  const MatchParams& p = *P;
  leaves.clear();
  for (int i = 1; i < n_states; ++i) {
    const State& x = pool[static_cast<std::size_t>(i)];
    const bool leaf = x.expanded && x.children == 0 && x.level >= p.th_minlevel;
    const bool incomplete =
        !x.expanded && st.stop != StopReason::kNoStates && (x.level >= p.th_minlevel || p.keep_partial);
    if (leaf || incomplete) leaves.push_back(i);
  }
  st.leaf_solutions = static_cast<std::int64_t>(leaves.size());
}

// Traditional (complete) solutions first, by level descending, then the incomplete ones. (Counting sort by
// that key: leaves are gathered by ascending state number, so the result is the order of a comparison sort by
// (complete first, level descending, state number).)
void InexactMatcher::Impl::order_leaves() {
  std::array<int, 2 * (kMaxNodes + 1) + 1> start{};
  auto bucket = [&](int id) {
    const State& x = pool[static_cast<std::size_t>(id)];
    return (x.expanded ? 0 : kMaxNodes + 1) + (kMaxNodes - x.level);
  };
  for (int id : leaves) ++start[static_cast<std::size_t>(bucket(id)) + 1];
  for (std::size_t b = 1; b < start.size(); ++b) start[b] += start[b - 1];
  sorted.resize(leaves.size());  // capacity reserved for every pool entry: no allocation
  for (int id : leaves) sorted[static_cast<std::size_t>(start[static_cast<std::size_t>(bucket(id))]++)] = id;
  leaves.swap(sorted);
}

// Subset condition (7.7.2, 7.7.3): a traditional solution is dropped when its match set is a subset of
// another traditional solution's; an incomplete one when it is a subset of a traditional solution's. Leaves
// come in order_leaves() order; the survivors stay in leaves.
void InexactMatcher::Impl::subset_condition(MatchStats& st) {
  std::size_t n_complete = 0;
  while (n_complete < leaves.size() && pool[static_cast<std::size_t>(leaves[n_complete])].expanded)
    ++n_complete;
  // Each leaf is compared with the complete solutions kept so far that have a higher level (a subset has a
  // lower level). Those are kept in level-descending order; the leaf scans the shortest pair list of the
  // inverted index (or, when the index is full, all of kept_cores), filters by the core sets, and only the
  // survivors walk the search tree. The answers are those of comparing it with every kept solution.
  kept_cores.clear();
  pair_entries.clear();
  bool index_full = false;
  auto pair_key = [](const State& y) {
    return static_cast<std::size_t>(y.r) * kMaxNodes + static_cast<std::size_t>(y.s);
  };
  auto covered = [&](const State& a, const KeptCore& b) {
    return a.cr.subset_of(b.cr) && a.cs.subset_of(b.cs) && subset(a, pool[static_cast<std::size_t>(b.id)]);
  };
  std::size_t kept = 0;
  for (std::size_t i = 0; i < leaves.size(); ++i) {
    const int id = leaves[i];
    const State& a = pool[static_cast<std::size_t>(id)];
    // Candidates come in level-descending order; those of a level <= a's cannot hold it.
    bool sub = false;
    auto check = [&](const KeptCore& b) {  // true: stop scanning
      if (b.level <= a.level) return true;
      sub = covered(a, b);
      return sub;
    };
    if (index_full) {
      for (const KeptCore& b : kept_cores)
        if (check(b)) break;
    } else {
      int best = -1, best_count = std::numeric_limits<int>::max();
      for (int q = id; q > 0 && best_count > 0; q = pool[static_cast<std::size_t>(q)].parent) {
        const int k = static_cast<int>(pair_key(pool[static_cast<std::size_t>(q)]));
        if (pair_count[static_cast<std::size_t>(k)] < best_count)
          best = k, best_count = pair_count[static_cast<std::size_t>(k)];
      }
      for (int e = best_count > 0 ? pair_head[static_cast<std::size_t>(best)] : -1; e >= 0;
           e = pair_entries[static_cast<std::size_t>(e)].next)
        if (check(kept_cores[static_cast<std::size_t>(pair_entries[static_cast<std::size_t>(e)].kept)]))
          break;
    }
    if (sub) {
      ++st.subset_removed;
      continue;
    }
    leaves[kept++] = id;
    if (i >= n_complete) continue;
    kept_cores.push_back(KeptCore{a.cr, a.cs, a.level, id});
    if (index_full) continue;
    if (pair_entries.size() + static_cast<std::size_t>(a.level) > pair_entries.capacity()) {
      index_full = true;
      continue;
    }
    const int kept_index = static_cast<int>(kept_cores.size()) - 1;
    for (int q = id; q > 0; q = pool[static_cast<std::size_t>(q)].parent) {
      const std::size_t k = pair_key(pool[static_cast<std::size_t>(q)]);
      const int e = static_cast<int>(pair_entries.size());
      pair_entries.push_back(PairEntry{-1, kept_index});
      if (pair_head[k] < 0) {
        pair_head[k] = e;
        pair_touched.push_back(static_cast<int>(k));
      } else {
        pair_entries[static_cast<std::size_t>(pair_tail[k])].next = e;
      }
      pair_tail[k] = e;
      ++pair_count[k];
    }
  }
  for (int k : pair_touched) {
    pair_head[static_cast<std::size_t>(k)] = pair_tail[static_cast<std::size_t>(k)] = -1;
    pair_count[static_cast<std::size_t>(k)] = 0;
  }
  pair_touched.clear();
  leaves.resize(kept);  // shrinking: no allocation
  st.solutions = static_cast<std::int64_t>(kept);
}

// Ranking key: cost + zeta U. For a state not fitted yet its cost is a lower bound and U_model is 0 (it needs
// the rotation; it is >= 0 once fitted), so the key is a lower bound of the final one, as the lazy top-k
// needs.
double InexactMatcher::Impl::ranking_key(const State& x) const {
  if (P->zeta <= 0) return x.cost;
  const int id = static_cast<int>(&x - pool.data());
  return x.cost + P->zeta * (unexplained(x) + unexplained_model(id));
}

// ranked[0 .. n) = the best n leaves by (key, state number), as a full sort would give them: a min-heap over
// the keys, where a lazily created state's key is its cost lower bound until it reaches the top and is
// fitted.
std::size_t InexactMatcher::Impl::rank_solutions(std::size_t n) {
  auto later = [](const HeapItem& a, const HeapItem& b) {
    return a.cost > b.cost || (a.cost == b.cost && a.id > b.id);
  };
  topk.clear();
  for (int id : leaves) topk.push_back(HeapItem{ranking_key(pool[static_cast<std::size_t>(id)]), 0, id});
  std::make_heap(topk.begin(), topk.end(), later);
  std::size_t got = 0;
  while (got < n) {
    std::pop_heap(topk.begin(), topk.end(), later);
    const int id = topk.back().id;
    topk.pop_back();
    State& x = pool[static_cast<std::size_t>(id)];
    if (!x.fitted) {
      finish(id);
      topk.push_back(HeapItem{ranking_key(x), 0, id});
      std::push_heap(topk.begin(), topk.end(), later);
      continue;
    }
    ranked[got++] = id;
  }
  return n;
}

// The reported solutions: the ranked states with their matches and paths copied out of the search tree.
void InexactMatcher::Impl::fill_solutions(std::size_t n) {
  const MatchParams& p = *P;
  for (std::size_t k = 0; k < n; ++k) {
    const State& x = pool[static_cast<std::size_t>(ranked[k])];
    Solution& sol = solutions[k];
    sol.rank = static_cast<int>(k) + 1;
    sol.state = ranked[k];
    sol.level = x.level;
    NodeMatch* m = &match_buf[k * kMaxNodes];
    int* path = &path_buf[k * kMaxNodes];
    int j = x.level;
    for (int q = ranked[k]; q > 0; q = pool[static_cast<std::size_t>(q)].parent) {
      const State& y = pool[static_cast<std::size_t>(q)];
      --j;
      m[j] = NodeMatch{S->id[static_cast<std::size_t>(y.s)], G->id[static_cast<std::size_t>(y.r)]};
      path[j] = y.child_index;
    }
    sol.matches = std::span<const NodeMatch>(m, static_cast<std::size_t>(x.level));
    sol.path = std::span<const int>(path, static_cast<std::size_t>(x.level));
    sol.arcs_matched = x.am;
    sol.arcs_inserted = x.ai;
    sol.arcs_deleted = x.ad;
    sol.node_diss = x.d_area;
    sol.arc_attr_diss = x.d_border;
    sol.arc_struct_diss = x.ai + x.ad;
    sol.rotfit_error = x.rotfit;
    sol.rotation = fitdata[static_cast<std::size_t>(ranked[k])].R;
    sol.cost = x.cost;
    sol.unexplained = unexplained(x) + unexplained_model(ranked[k]);
    sol.complete = x.expanded;
    sol.partial = x.level < p.th_minlevel;
    sol.degenerate = x.degenerate;
  }
}

// The result and its statistics: best state, cost ratio of the two best, rotation fits.
void InexactMatcher::Impl::set_result_stats(std::size_t n, MatchStats& st) {
  result.solutions = std::span<const Solution>(solutions.data(), n);
  st.best_state = n > 0 ? solutions[0].state : -1;
  if (n >= 2)
    st.cost_ratio = solutions[0].cost > 0 ? solutions[1].cost / solutions[0].cost
                                          : std::numeric_limits<double>::infinity();
  else
    st.cost_ratio = std::numeric_limits<double>::quiet_NaN();
  st.fits_fast = fit_stats.fast;
  st.fits_fallback = fit_stats.fallback;
}

// Subset condition: is a's match set a proper subset of b's?
bool InexactMatcher::Impl::subset(const State& a, const State& b) {
  if (a.level >= b.level || !a.cr.subset_of(b.cr) || !a.cs.subset_of(b.cs)) return false;
  const int bi = static_cast<int>(&b - pool.data());
  for (int k = bi; k > 0; k = pool[static_cast<std::size_t>(k)].parent)
    mark[static_cast<std::size_t>(pool[static_cast<std::size_t>(k)].r)] = pool[static_cast<std::size_t>(k)].s;
  bool ok = true;
  for (int k = static_cast<int>(&a - pool.data()); k > 0 && ok; k = pool[static_cast<std::size_t>(k)].parent)
    ok = mark[static_cast<std::size_t>(pool[static_cast<std::size_t>(k)].r)] ==
         pool[static_cast<std::size_t>(k)].s;
  for (int k = bi; k > 0; k = pool[static_cast<std::size_t>(k)].parent)
    mark[static_cast<std::size_t>(pool[static_cast<std::size_t>(k)].r)] = -1;
  return ok;
}

// Scene side: every unmatched scene face next to the match counts.
double InexactMatcher::Impl::unexplained(const State& x) const {
  return open_neighbour_share(*S, x.cs, [](int) { return 1.0; });
}

// Model side (needs x's rotation, so 0 until x is fitted): unmatched reference faces next to the match
// count as far as the rotation turns them toward the sensor (weight 1 within 60 deg of the observer,
// falling to 0 at 90 deg, where faces are seen edge-on): in a wrong pose of a part that looks like another
// part, such faces should have been seen next to the match.
double InexactMatcher::Impl::unexplained_model(int id) const {
  const State& x = pool[static_cast<std::size_t>(id)];
  if (!x.fitted || x.degenerate) return 0.0;
  const Mat3& R = fitdata[static_cast<std::size_t>(id)].R;
  constexpr double kCosFull = 0.5;  // cos 60 deg
  return open_neighbour_share(*G, x.cr, [&](int i) {
    return std::clamp((R * G->normal[static_cast<std::size_t>(i)]).dot(S->observer) / kCosFull, 0.0, 1.0);
  });
}

}  // namespace fs::host::match
