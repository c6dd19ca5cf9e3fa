// The inexact matcher's public interface (inexact.hpp): working memory sized once, match() as the sequence
// search (search.cpp) -> solutions (solutions.cpp); owned copies and state ids of solutions.
#include "host/match/inexact.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>

#include "common/error.hpp"
#include "host/match/inexact_impl.hpp"

namespace fs::host::match {

namespace {

class SteadyClock final : public MatchClock {
 public:
  std::int64_t now_ns() const override {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
  }
};

// Pool entries for the limits (the root included).
std::size_t state_capacity(const MatcherLimits& l) {
  return static_cast<std::size_t>(std::max<std::int64_t>(l.max_states, 1)) + 1;
}

}  // namespace

std::string_view stop_name(StopReason r) {
  switch (r) {
    case StopReason::kNoStates:
      return "no states left";
    case StopReason::kSolutionsFound:
      return "solutions found";
    case StopReason::kStateBudget:
      return "state budget";
    case StopReason::kTimeBudget:
      return "time budget";
  }
  return "?";
}

const MatchClock& steady_match_clock() {
  static const SteadyClock clock;
  return clock;
}

InexactMatcher::Impl::Impl(const MatcherLimits& l) : limits(l), table(state_capacity(l)) {
  if (limits.max_states < 1) limits.max_states = 1;
  if (limits.max_reported < 1) limits.max_reported = 1;
  const auto cap = static_cast<std::size_t>(limits.max_states) + 1;
  pool.resize(cap + 1);  // + 1: the scratch entry a candidate is built in when the pool is full
  fitdata.resize(cap + 1);
  heap.reserve(cap);
  leaves.reserve(cap);
  sorted.reserve(cap);
  kept_cores.reserve(cap);
  pair_entries.reserve(8 * cap);
  pair_head.assign(static_cast<std::size_t>(kMaxNodes) * kMaxNodes, -1);
  pair_tail.assign(static_cast<std::size_t>(kMaxNodes) * kMaxNodes, -1);
  pair_count.assign(static_cast<std::size_t>(kMaxNodes) * kMaxNodes, 0);
  pair_touched.reserve(static_cast<std::size_t>(kMaxNodes) * kMaxNodes);
  topk.reserve(cap);
  ranked.resize(static_cast<std::size_t>(limits.max_reported));
  solutions.resize(static_cast<std::size_t>(limits.max_reported));
  match_buf.resize(static_cast<std::size_t>(limits.max_reported) * kMaxNodes);
  path_buf.resize(static_cast<std::size_t>(limits.max_reported) * kMaxNodes);
  pair_gamma.resize(static_cast<std::size_t>(kMaxNodes) * kMaxNodes);
  pair_darea.resize(static_cast<std::size_t>(kMaxNodes) * kMaxNodes);
  pair_degree_fail.resize(static_cast<std::size_t>(kMaxNodes) * kMaxNodes);
  pair_area_fail.resize(static_cast<std::size_t>(kMaxNodes) * kMaxNodes);
  r2s.fill(-1);
  s2r.fill(-1);
  mark.fill(-1);
}

InexactMatcher::InexactMatcher(const MatcherLimits& limits) : impl_(std::make_unique<Impl>(limits)) {}
InexactMatcher::~InexactMatcher() = default;
void InexactMatcher::set_clock(const MatchClock* clock) {
  impl_->clock = clock ? clock : &steady_match_clock();
}
const MatcherLimits& InexactMatcher::limits() const { return impl_->limits; }
const CompactGraph& InexactMatcher::scene_graph() const { return *impl_->S; }

SearchScope full_scope() {
  SearchScope s;
  s.first_refs = ~NodeSet{};
  s.scene = ~NodeSet{};
  return s;
}

const MatchResult& InexactMatcher::match(const Pfrg& scene, const Pfrg& ref, const MatchParams& params) {
  impl_->scoped = false;
  return run_match(scene, ref, params);
}

const MatchResult& InexactMatcher::match(const Pfrg& scene, const Pfrg& ref, const MatchParams& params,
                                         const SearchScope& scope) {
  impl_->scoped = true;
  impl_->scope = scope;
  return run_match(scene, ref, params);
}

const MatchResult& InexactMatcher::run_match(const Pfrg& scene, const Pfrg& ref, const MatchParams& params) {
  Impl& m = *impl_;
  m.S->load(scene);
  m.G->load(ref);
  m.P = &params;
  m.table.reset();
  m.budget = std::min<std::int64_t>(m.limits.max_states, std::max<std::int64_t>(params.max_states, 1));
  m.result = MatchResult{};
  m.run(m.result.stats);
  m.collect(m.result.stats);
  return m.result;
}

OwnedSolution to_owned(const Solution& s) {
  OwnedSolution o;
  o.rank = s.rank;
  o.state = s.state;
  o.path.assign(s.path.begin(), s.path.end());
  o.matches.assign(s.matches.begin(), s.matches.end());
  o.level = s.level;
  o.arcs_matched = s.arcs_matched;
  o.arcs_inserted = s.arcs_inserted;
  o.arcs_deleted = s.arcs_deleted;
  o.node_diss = s.node_diss;
  o.arc_attr_diss = s.arc_attr_diss;
  o.arc_struct_diss = s.arc_struct_diss;
  o.rotfit_error = s.rotfit_error;
  o.rotation = s.rotation;
  o.cost = s.cost;
  o.unexplained = s.unexplained;
  o.complete = s.complete;
  o.partial = s.partial;
  o.degenerate = s.degenerate;
  return o;
}

std::string state_id(std::string_view prefix, std::span<const int> path) {
  std::string out(prefix);
  char buf[16];
  for (int k : path) {
    const int n = std::snprintf(buf, sizeof buf, ".%d", k);
    out.append(buf, static_cast<std::size_t>(n));
  }
  return out;
}

}  // namespace fs::host::match
