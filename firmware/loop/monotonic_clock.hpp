#pragma once
// The real loop clock: CLOCK_MONOTONIC, clock_nanosleep(TIMER_ABSTIME) (absolute deadlines, no drift).
#include "common/monotonic_time.hpp"
#include "firmware/device/clock.hpp"

namespace fs::fw {

class MonotonicClock final : public Clock {
 public:
  Nanos now() override { return monotonic_ns(); }
  void sleep_until(Nanos t) override { sleep_until_monotonic_ns(t); }
};

}  // namespace fs::fw
