#pragma once
// Internal to the inexact matcher (see README.md): the matcher's working memory and the steps of match(),
// implemented by stage in search.cpp (best-first search, ch. 7.2-7.6) and solutions.cpp (solutions, ch. 7.7).
//
// Without changing any result, the search saves work:
//  - Lazy rotation fits. A new state of level >= 2 is created with B and sum gamma but without its eigen
//    solve when the conditions that need e_rotfit (8 cost threshold, 9.3 rotation fit similarity) are already
//    decided by bounds of lambda_min(B): from below the parent's lambda_min (Weyl: B = B_parent + gamma A, A
//    PSD), from above the Rayleigh quotient of B at the parent's quaternion, both widened by 1e-9 trace(B)
//    (far above the solver's error). Such a state enters the priority queue with the cost lower bound; when
//    it reaches the top it is fitted (same solver, same inputs, so bit-identical) and re-queued if another
//    state now comes first, so states are expanded in exactly the order of eager fits. Most created states
//    are never expanded, and their fits are saved. Reported solutions are fitted on demand, and selected by a
//    lazy top-k over the cost lower bounds instead of sorting every candidate.
//  - The visibility check of new level-2 states (the one check that needs a rotation before the state exists)
//    uses the closed-form two-pair fit (two_pair_fit, rotation_fit.hpp) when it is well conditioned and both
//    rotated normals are more than 1e-7 away from the cone (the solver's rotation differs by < 1e-9 there);
//    otherwise the solver. lambda_min is then known in closed form (bounds +- 1e-9 trace B).
//  - The duplicate test (duplicate_table.hpp) starts small, grows inside its reserved memory and answers most
//    misses from a Bloom filter; its slot is prefetched once the match-set hash is known.
//  - The rotation data (B, R, q) lives in a parallel array (FitData): tree walks, duplicate tests and heap
//    keys touch smaller states.
//  - Per-match tables of the pair-static quantities (gamma, D_area term, node degree condition), supernode
//    candidates counted in bulk, heap entries that carry their key, hash slots that carry the hash, and the
//    candidate state built in place in the pool (no temporary state per candidate).
// The search time is measured by bench_match; tests/host/match checks the solutions against golden lists.
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "host/match/compact_graph.hpp"
#include "host/match/duplicate_table.hpp"
#include "host/match/inexact.hpp"
#include "host/match/node_set.hpp"
#include "host/match/rotation_fit.hpp"
#include "host/match/search_state.hpp"
#include "host/match/state_heap.hpp"

namespace fs::host::match {

struct InexactMatcher::Impl {
  using State = detail::State;
  using FitData = detail::FitData;
  using HeapItem = detail::HeapItem;

  MatcherLimits limits;
  const MatchClock* clock = &steady_match_clock();
  SearchScope scope;  // when scoped (match() with a scope)
  bool scoped = false;
  std::unique_ptr<CompactGraph> S = std::make_unique<CompactGraph>();  // scene
  std::unique_ptr<CompactGraph> G = std::make_unique<CompactGraph>();  // reference
  std::vector<State> pool;
  std::vector<FitData> fitdata;  // parallel to pool
  detail::StateHeap heap;        // open states, min key first
  detail::DuplicateTable table;  // duplicate test (new match condition)
  std::vector<int> leaves;       // solution candidates
  std::vector<int> sorted;       // counting sort buffer of the leaves
  // Kept complete solutions of the subset condition, contiguous (core sets and level copied out of the pool).
  struct KeptCore {
    NodeSet cr, cs;
    int level, id;
  };
  std::vector<KeptCore> kept_cores;
  // Inverted index of kept_cores by match pair (r * kMaxNodes + s): each list holds, in insertion (= level-
  // descending) order, the kept complete solutions that contain the pair. A leaf can only be a subset of a
  // solution in the list of each of its pairs, so it scans the shortest one. Entries live in a fixed array;
  // when it is full the scan falls back to all of kept_cores (same answers).
  struct PairEntry {
    int next, kept;
  };
  std::vector<PairEntry> pair_entries;
  std::vector<int> pair_head, pair_tail, pair_count;
  std::vector<int> pair_touched;
  std::vector<HeapItem> topk;  // lazy top-k selection of the reported solutions
  std::vector<int> ranked;     // the reported solutions' states, best first
  std::vector<Solution> solutions;
  std::vector<NodeMatch> match_buf;
  std::vector<int> path_buf;
  std::array<int, kMaxNodes> r2s{}, s2r{}, mark{};
  // Pair tables (index r * kMaxNodes + s), filled per match for the graphs' sizes.
  std::vector<double> pair_gamma, pair_darea;
  std::vector<std::uint8_t> pair_degree_fail;
  std::vector<std::uint8_t> pair_area_fail;  // one-sided area condition (th_area_ratio)
  bool unit_normals = false;                 // every real normal of both graphs has length 1 within 1e-12
  MatchResult result;
  const MatchParams* P = nullptr;
  int n_states = 0;  // used pool entries (root included)
  std::int64_t budget = 0;
  FastFitStats fit_stats;

  explicit Impl(const MatcherLimits& l);

  // ---- costs (ch. 7.6) ----
  double cost_of(const State& c) const { return cost_with(c, c.rotfit); }
  // The cost with a given rotation fit error (monotone non-decreasing in it: epsilon >= 0).
  double cost_with(const State& c, double rotfit) const {
    double cost = 0;
    if (c.level > 0) cost += (P->alpha * c.d_area + P->epsilon * rotfit) / c.level;
    const int arcs = c.am + c.ai + c.ad;
    if (arcs > 0) cost += (P->beta * c.d_border + P->gamma * c.ai + P->delta * c.ad) / arcs;
    return cost;
  }
  static double rotfit_of(const State& c, double lambda) {
    return c.sum_gamma > 0 ? lambda / (2.0 * c.sum_gamma) : 0.0;
  }
  void fit(int ci, int pi);
  // Completes a lazily created state: the fit its creation skipped, and the exact cost.
  void finish(int id);

  // ---- the search (search.cpp) ----
  struct SearchSetup;
  struct Expansion;
  struct RefCandidate;
  struct Candidate;
  void run(MatchStats& st);
  SearchSetup setup_search();
  void fill_pair_tables();
  void start_search(MatchStats& st);
  bool global_stop(const SearchSetup& su, MatchStats& st) const;
  int pop_fitted();
  Expansion begin_expansion(const SearchSetup& su, int pi, MatchStats& st);
  void expand_reference(const SearchSetup& su, Expansion& ex, int r, MatchStats& st);
  void try_pair(const SearchSetup& su, Expansion& ex, RefCandidate& rc, int s, MatchStats& st);
  bool backward_visible(const SearchSetup& su, const Expansion& ex, Candidate& cd, MatchStats& st);
  void count_core_arcs(const Expansion& ex, const Candidate& cd, int& dam, int& dai, double& dborder) const;
  bool passes_thresholds(const SearchSetup& su, const Expansion& ex, Candidate& cd, double darea,
                         double dborder, MatchStats& st);
  void commit_state(Expansion& ex, Candidate& cd, const NodeSet& cr, const NodeSet& cs, MatchStats& st);
  void end_expansion(const SearchSetup& su, const Expansion& ex, MatchStats& st);
  // candidate construction
  void build(const SearchSetup& su, const Expansion& ex, Candidate& cd) const;
  void fit_now(const Expansion& ex, Candidate& cd);
  void lazy_bounds(Candidate& cd, double lam_lo, double lam_hi) const;
  void lazy_from_parent(const Expansion& ex, Candidate& cd) const;
  // state map and duplicate test
  void heap_push(int x) {
    const State& st = pool[static_cast<std::size_t>(x)];
    heap.push(HeapItem{st.cost, st.level, x});
  }
  bool same_matches(const State& e, int r, int s) const;
  bool exists(std::uint64_t h, const NodeSet& cr, const NodeSet& cs, int r, int s) const;
  void load_map(int st, int value_sign);
  // Search-wide progress (reset by start_search).
  bool stop = false;
  std::int64_t solutions_found = 0;
  int best_leaf = -1;

  // ---- solutions (solutions.cpp) ----
  void collect(MatchStats& st);
  void gather_leaves(MatchStats& st);
  void order_leaves();
  void subset_condition(MatchStats& st);
  std::size_t rank_solutions(std::size_t n);
  void fill_solutions(std::size_t n);
  void set_result_stats(std::size_t n, MatchStats& st);
  bool subset(const State& a, const State& b);
  double ranking_key(const State& x) const;
  double unexplained(const State& x) const;
  double unexplained_model(int id) const;
};

}  // namespace fs::host::match
