#include "hw-sim/sim_clock.hpp"

#include <time.h>

#include <cerrno>

namespace fs::sim {

namespace {
fw::Nanos monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<fw::Nanos>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}
}  // namespace

SimClock::SimClock(fw::Nanos start, bool realtime) : now_(start), realtime_(realtime) {
  if (realtime_) offset_ = start - monotonic_ns();
}

fw::Nanos SimClock::now() { return realtime_ ? monotonic_ns() + offset_ : now_.load(); }

void SimClock::sleep_until(fw::Nanos t) {
  if (!realtime_) {
    if (t >= late_from_ && t < late_to_) t += late_delay_;
    fw::Nanos cur = now_.load();
    while (t > cur && !now_.compare_exchange_weak(cur, t)) {
    }
    return;
  }
  const fw::Nanos target = t - offset_;
  timespec ts{static_cast<time_t>(target / 1'000'000'000), static_cast<long>(target % 1'000'000'000)};
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

void SimClock::advance(fw::Nanos dt) {
  if (!realtime_ && dt > 0) now_.fetch_add(dt);
}

}  // namespace fs::sim
