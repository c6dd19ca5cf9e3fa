#include "hw-sim/sim_clock.hpp"

#include "common/monotonic_time.hpp"

namespace fs::sim {

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
  sleep_until_monotonic_ns(t - offset_);
}

void SimClock::advance(fw::Nanos dt) {
  if (!realtime_ && dt > 0) now_.fetch_add(dt);
}

}  // namespace fs::sim
