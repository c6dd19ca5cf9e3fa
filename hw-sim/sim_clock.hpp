#pragma once
// Simulated clock: virtual time that advances only when the loop sleeps (deterministic HIL runs, faster than
// real time), or real time (CLOCK_MONOTONIC) with the same interface when realtime = true.
#include <atomic>

#include "firmware/device/clock.hpp"

namespace fs::sim {

class SimClock final : public fw::Clock {
 public:
  explicit SimClock(fw::Nanos start = 1'000'000'000, bool realtime = false);
  fw::Nanos now() override;
  void sleep_until(fw::Nanos t) override;
  // Moves virtual time forward (e.g. a twin that models a blocking device call). No-op in realtime mode.
  void advance(fw::Nanos dt);
  bool realtime() const { return realtime_; }
  // Fault injection (virtual mode): wake-ups for targets in [from, to) happen `delay` late (a loop that
  // misses its deadlines, e.g. a preempted thread).
  void inject_lateness(fw::Nanos from, fw::Nanos to, fw::Nanos delay) {
    late_from_ = from;
    late_to_ = to;
    late_delay_ = delay;
  }

 private:
  std::atomic<fw::Nanos> now_;
  bool realtime_;
  fw::Nanos offset_ = 0;
  fw::Nanos late_from_ = 0, late_to_ = 0, late_delay_ = 0;
};

}  // namespace fs::sim
