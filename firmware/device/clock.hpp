#pragma once
// Time source of the controller loop. Real: CLOCK_MONOTONIC + clock_nanosleep(TIMER_ABSTIME).
// Simulated (hw-sim/sim_clock.hpp): virtual time that advances on sleep_until, so HIL runs are deterministic.
#include <cstdint>

namespace fs::fw {

using Nanos = std::int64_t;

class Clock {
 public:
  virtual ~Clock() = default;
  virtual Nanos now() = 0;
  // Sleeps until the absolute time t (returns at once when t is in the past).
  virtual void sleep_until(Nanos t) = 0;
};

}  // namespace fs::fw
