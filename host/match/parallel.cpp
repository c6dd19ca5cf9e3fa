#include "host/match/parallel.hpp"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>

namespace fs::host::match {

ParallelMatcher::ParallelMatcher(int threads, const MatcherLimits& limits) {
  if (threads <= 0) threads = static_cast<int>(std::max(1U, std::thread::hardware_concurrency()));
  for (int i = 0; i < threads; ++i) matchers_.push_back(std::make_unique<InexactMatcher>(limits));
}
ParallelMatcher::~ParallelMatcher() = default;
int ParallelMatcher::threads() const { return static_cast<int>(matchers_.size()); }

std::vector<ReferenceResult> ParallelMatcher::match(const Pfrg& scene, std::span<const Pfrg> refs,
                                                    const MatchParams& params, std::size_t max_solutions) {
  std::vector<ReferenceResult> results(refs.size());
  // Largest references first (their searches take longest), so that no thread is left with a big one at the
  // end; results stay in reference order, so the order of work does not show.
  std::vector<std::size_t> order(refs.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return refs[a].nodes.size() > refs[b].nodes.size(); });
  std::atomic<std::size_t> next{0};
  std::exception_ptr error;
  std::mutex error_mutex;
  auto worker = [&](InexactMatcher& m) {
    for (;;) {
      const std::size_t k = next.fetch_add(1);
      if (k >= refs.size()) return;
      const std::size_t i = order[k];
      try {
        const MatchResult& r = m.match(scene, refs[i], params);
        ReferenceResult& out = results[i];
        out.stats = r.stats;
        const std::size_t n = std::min(max_solutions, r.solutions.size());
        out.solutions.reserve(n);
        for (std::size_t k = 0; k < n; ++k) out.solutions.push_back(to_owned(r.solutions[k]));
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
      }
    }
  };
  const std::size_t nthreads = std::min(matchers_.size(), std::max<std::size_t>(refs.size(), 1));
  if (nthreads <= 1) {
    worker(*matchers_[0]);
  } else {
    std::vector<std::jthread> pool;
    pool.reserve(nthreads - 1);
    for (std::size_t t = 1; t < nthreads; ++t) pool.emplace_back([&, t] { worker(*matchers_[t]); });
    worker(*matchers_[0]);
  }
  if (error) std::rethrow_exception(error);
  return results;
}

}  // namespace fs::host::match
