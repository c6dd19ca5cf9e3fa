#pragma once
// Real-time setup of the loop thread for a real board (--rt): SCHED_FIFO priority, mlockall(MCL_CURRENT |
// MCL_FUTURE), CPU affinity, and a CPU wake-up latency limit (PM QoS, /dev/cpu_dma_latency: the CPUs do not
// enter idle states slower to leave than that, as cyclictest does for its run). Each step that is not
// permitted (no CAP_SYS_NICE / RLIMIT_RTPRIO / RLIMIT_MEMLOCK, CPU not present, no access to the QoS device)
// produces a warning and the program continues without it.
#include <string>
#include <vector>

namespace fs::fw {

struct RealtimeRequest {
  int priority = 80;  // SCHED_FIFO 1..99
  int cpu = -1;       // pin the calling thread to this CPU; -1 = leave
  bool lock_memory = true;
  int cpu_latency_us = 0;  // PM QoS CPU wake-up latency limit while the result lives; -1 = leave
};

// A held PM QoS request (the limit holds while the device stays open; closed by the destructor).
class CpuLatencyLimit {
 public:
  CpuLatencyLimit() = default;
  // Opens `device` and writes the limit; false with *error set when that is refused.
  bool request(int microseconds, std::string* error, const char* device = "/dev/cpu_dma_latency");
  bool held() const { return fd_ >= 0; }
  CpuLatencyLimit(CpuLatencyLimit&& o) noexcept : fd_(o.fd_) { o.fd_ = -1; }
  CpuLatencyLimit& operator=(CpuLatencyLimit&& o) noexcept;
  CpuLatencyLimit(const CpuLatencyLimit&) = delete;
  CpuLatencyLimit& operator=(const CpuLatencyLimit&) = delete;
  ~CpuLatencyLimit();

 private:
  int fd_ = -1;
};

// Keep it alive for the loop's run: the CPU latency limit ends with it.
struct RealtimeResult {
  bool fifo = false, locked = false, pinned = false;
  CpuLatencyLimit cpu_latency;
  std::vector<std::string> warnings;
};

RealtimeResult apply_realtime(const RealtimeRequest& req);

}  // namespace fs::fw
