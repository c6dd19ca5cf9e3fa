#pragma once
// CLOCK_MONOTONIC in nanoseconds: the clock of the firmware loop and the real device timestamps (GPIO edge
// events, CAN and V4L2 buffers), of the simulated clock in real-time mode and of the host's stream timeouts.
#include <time.h>

#include <cerrno>
#include <cstdint>

namespace fs {

inline std::int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// Sleeps until the absolute CLOCK_MONOTONIC time t (ns), resuming after signals (no drift across periods).
inline void sleep_until_monotonic_ns(std::int64_t t) {
  const timespec ts{static_cast<time_t>(t / 1'000'000'000), static_cast<long>(t % 1'000'000'000)};
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

}  // namespace fs
