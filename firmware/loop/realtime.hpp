#pragma once
// Real-time setup of the loop thread for a real board (--rt): SCHED_FIFO priority, mlockall(MCL_CURRENT |
// MCL_FUTURE) and CPU affinity. Each step that is not permitted (no CAP_SYS_NICE / RLIMIT_RTPRIO /
// RLIMIT_MEMLOCK, CPU not present) produces a warning and the program continues without it.
#include <string>
#include <vector>

namespace fs::fw {

struct RealtimeRequest {
  int priority = 80;  // SCHED_FIFO 1..99
  int cpu = -1;       // pin the calling thread to this CPU; -1 = leave
  bool lock_memory = true;
};

struct RealtimeResult {
  bool fifo = false, locked = false, pinned = false;
  std::vector<std::string> warnings;
};

RealtimeResult apply_realtime(const RealtimeRequest& req);

// Real-time clock for the controller: CLOCK_MONOTONIC + clock_nanosleep(TIMER_ABSTIME).
}  // namespace fs::fw
