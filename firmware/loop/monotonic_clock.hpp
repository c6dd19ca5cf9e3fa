#pragma once
// The real loop clock: CLOCK_MONOTONIC, clock_nanosleep(TIMER_ABSTIME) (absolute deadlines, no drift).
#include <time.h>

#include <cerrno>

#include "firmware/device/clock.hpp"

namespace fs::fw {

class MonotonicClock final : public Clock {
 public:
  Nanos now() override {
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<Nanos>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
  }
  void sleep_until(Nanos t) override {
    timespec ts{static_cast<time_t>(t / 1'000'000'000), static_cast<long>(t % 1'000'000'000)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
  }
};

}  // namespace fs::fw
