#pragma once
// Test and benchmark helper: the calling thread's CPU time in seconds (CLOCK_THREAD_CPUTIME_ID), for timing a
// piece of work on this shared, noisy machine without counting the time the thread was descheduled.
#include <ctime>

namespace fs::test {

inline double thread_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + static_cast<double>(t.tv_nsec) * 1e-9;
}

}  // namespace fs::test
