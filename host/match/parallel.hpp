#pragma once
// One scene against N references: N independent searches spread over a pool of threads, one preallocated
// InexactMatcher per thread. Results are indexed by reference and do not depend on the thread count (each
// search is deterministic; only a time budget can make them differ).
#include <memory>
#include <span>
#include <vector>

#include "host/match/inexact.hpp"

namespace fs::host::match {

struct ReferenceResult {
  std::vector<OwnedSolution> solutions;  // best first
  MatchStats stats;
};

class ParallelMatcher {
 public:
  // threads <= 0: std::thread::hardware_concurrency().
  explicit ParallelMatcher(int threads = 0, const MatcherLimits& limits = {});
  ~ParallelMatcher();
  int threads() const;

  // results[i] belongs to refs[i]. Keeps at most max_solutions solutions per reference.
  std::vector<ReferenceResult> match(const Pfrg& scene, std::span<const Pfrg> refs, const MatchParams& params,
                                     std::size_t max_solutions = 16);

 private:
  std::vector<std::unique_ptr<InexactMatcher>> matchers_;
};

}  // namespace fs::host::match
