#pragma once
// Inexact attributed subgraph matching of PFRGs (thesis ch. 7): best-first search in a tree of states, each
// holding the match set, core / terminal sets (bitsets), arc counts, dissimilarities, the accumulated
// rotation fit matrix B and a cost. Pruning conditions of table 7.6 in order (each switchable and counted),
// rotation fit of ch. 7.5, costs of 7.6, global stops of 7.4, solutions of 7.7 (min level, subset condition,
// incomplete solutions after a global stop, ordered by cost).
//
// Fixed memory: an InexactMatcher is sized once (state pool, priority queue, duplicate-test hash set,
// solution buffers); match() performs no heap allocation. Exhausting the pool is a global stop ("state
// budget") with incomplete solutions, not an error.
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/calibration.hpp"
#include "host/match/compact_graph.hpp"
#include "host/match/node_set.hpp"
#include "host/match/params.hpp"
#include "host/pfrg/pfrg.hpp"

namespace fs::host::match {

struct NodeMatch {
  int scene = 0;  // scene PFRG node id
  int ref = 0;    // reference PFRG node id
  bool operator==(const NodeMatch&) const = default;
};

enum class StopReason { kNoStates, kSolutionsFound, kStateBudget, kTimeBudget };
std::string_view stop_name(
    StopReason r);  // "no states left", "solutions found", "state budget", "time budget"

// One solution (a leaf state of the search tree). Spans point into the matcher's buffers: valid until the
// next match() on the same matcher (copy with to_owned()).
struct Solution {
  int rank = 0;                        // 1 = best
  int state = 0;                       // state number = creation order (root = 0)
  std::span<const int> path;           // child index per level from the root: {9, 1, 1} = "<name>.9.1.1"
  std::span<const NodeMatch> matches;  // in the order they were established
  int level = 0;                       // nodes matched
  int arcs_matched = 0, arcs_inserted = 0, arcs_deleted = 0;
  double node_diss = 0.0;            // D_area
  double arc_attr_diss = 0.0;        // D_border
  double arc_struct_diss = 0.0;      // A_ins + A_del
  double rotfit_error = 0.0;         // e_rotfit = sum gamma |R r - s|^2 / (2 sum gamma)
  Mat3 rotation = Mat3::Identity();  // x_scene = rotation * x_ref (directions)
  double cost = 0.0;
  double unexplained = 0.0;  // U: unmatched neighbour area share (params.hpp: zeta); ranked by cost + zeta U
  bool complete = true;      // false: unexpanded state collected after a global stop (7.7.3)
  bool partial = false;      // level < TH_minlevel (reported only with keep_partial)
  bool degenerate = false;   // matched reference normals all parallel: rotation free about that axis
};

struct MatchStats {
  std::int64_t states_created = 0;  // excluding the root ("states investigated")
  std::int64_t states_expanded = 0;
  std::int64_t candidates = 0;  // candidate pairs examined (after the connectivity condition)
  std::array<std::int64_t, kConditionCount> removed{};  // candidates removed, per condition (table 7.6)
  std::int64_t leaf_solutions = 0;                      // solutions before the subset condition
  std::int64_t subset_removed = 0;
  std::int64_t solutions = 0;  // after the subset condition (may exceed the reported capacity)
  int best_state = -1;         // state number of solution 1
  double cost_ratio = 0.0;     // cost(solution 2) / cost(solution 1); NaN with < 2 solutions (with zeta > 0
                               // the solutions are ranked by cost + zeta U, so it can be < 1)
  StopReason stop = StopReason::kNoStates;
  double time_ms = 0.0;
  // When the lowest-cost complete leaf was found (states created so far, time since the start).
  std::int64_t states_to_best = 0;
  double time_to_best_ms = 0.0;
  // Rotation fits of created states: fast path (Newton + inverse iteration) / full eigen solver fallback.
  std::int64_t fits_fast = 0, fits_fallback = 0;
};

struct MatchResult {
  std::span<const Solution> solutions;  // best first, at most MatcherLimits::max_reported
  MatchStats stats;
};

// Where a search may go, as indices into the graphs' nodes (bit i = nodes[i]).
// - first_refs: the reference nodes a search starts from. For a reference with rotation symmetries, one face
//   of each orbit (face_orbit_representatives) gives every distinct solution: a search started from another
//   face of the orbit finds the symmetric images of the same solutions, at the same cost, so the budget is
//   not spent on those copies.
// - scene: the scene nodes it may match (a second search of one part without the object a first one found).
struct SearchScope {
  NodeSet first_refs;
  NodeSet scene;
};
// Every node of graphs of up to kMaxNodes nodes.
SearchScope full_scope();

struct MatcherLimits {
  std::int64_t max_states = 50000;  // state pool size (effective budget = min(this, params.max_states))
  int max_reported = 64;            // solutions kept in the result
};

// Time source for the time budget (inject a fake in tests).
class MatchClock {
 public:
  virtual ~MatchClock() = default;
  virtual std::int64_t now_ns() const = 0;
};
const MatchClock& steady_match_clock();

class InexactMatcher {
 public:
  explicit InexactMatcher(const MatcherLimits& limits = {});
  ~InexactMatcher();
  InexactMatcher(const InexactMatcher&) = delete;
  InexactMatcher& operator=(const InexactMatcher&) = delete;

  // Matches scene against reference. No heap allocation. Throws fs::Error if a graph exceeds kMaxNodes nodes.
  const MatchResult& match(const Pfrg& scene, const Pfrg& ref, const MatchParams& params);
  // The same within a scope (SearchScope): the search starts only from scope.first_refs and matches only
  // the scene nodes in scope.scene.
  const MatchResult& match(const Pfrg& scene, const Pfrg& ref, const MatchParams& params,
                           const SearchScope& scope);
  // The scene of the last match() in the matchers' working form (its node indices are SearchScope::scene's).
  const CompactGraph& scene_graph() const;
  void set_clock(const MatchClock* clock);  // nullptr = steady clock
  const MatcherLimits& limits() const;

 private:
  const MatchResult& run_match(const Pfrg& scene, const Pfrg& ref, const MatchParams& params);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Owning copy of a solution (for the recognition stage).
struct OwnedSolution {
  int rank = 0, state = 0;
  std::vector<int> path;
  std::vector<NodeMatch> matches;
  int level = 0, arcs_matched = 0, arcs_inserted = 0, arcs_deleted = 0;
  double node_diss = 0, arc_attr_diss = 0, arc_struct_diss = 0, rotfit_error = 0;
  Mat3 rotation = Mat3::Identity();
  double cost = 0, unexplained = 0;
  bool complete = true, partial = false, degenerate = false;
};
OwnedSolution to_owned(const Solution& s);

// "prefix.9.1.1"
std::string state_id(std::string_view prefix, std::span<const int> path);

}  // namespace fs::host::match
