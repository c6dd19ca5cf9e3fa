#pragma once
// Cia402Master on one end of a socketpair, the hw-sim Cia402Twin on the other, on a manual clock.
#include <unistd.h>

#include <functional>

#include "firmware/backends/can_port.hpp"
#include "firmware/backends/cia402_master.hpp"
#include "hw-sim/can/cia402_twin.hpp"
#include "test_clock.hpp"

namespace fs::test {

struct CanRig {
  explicit CanRig(fw::Cia402Config mcfg = {}, sim::Cia402TwinConfig tcfg = {})
      : fds(fw::CanPort::socketpair_fds()),
        port(fds[0], true),
        master(port, mcfg),
        twin(fds[1], clock, tcfg) {}
  ~CanRig() { ::close(fds[1]); }

  // One loop period: time advances, the twin then the master are serviced.
  fw::GalvoStatus tick(fw::Nanos dt = kMs) {
    clock.advance(dt);
    twin.poll();
    status = master.poll(clock.now());
    return status;
  }
  // Ticks until pred(status) or the time budget is spent; returns whether pred became true.
  bool run_until(const std::function<bool(const fw::GalvoStatus&)>& pred, fw::Nanos budget,
                 fw::Nanos dt = kMs) {
    const fw::Nanos end = clock.now() + budget;
    while (clock.now() < end) {
      if (pred(tick(dt))) return true;
    }
    return false;
  }
  void run_for(fw::Nanos t, fw::Nanos dt = kMs) {
    const fw::Nanos end = clock.now() + t;
    while (clock.now() < end) tick(dt);
  }
  bool enable() {
    master.enable(clock.now());
    return run_until([](const fw::GalvoStatus& s) { return s.enabled; }, 500 * kMs);
  }
  bool move(std::int32_t step, fw::Nanos budget = 2000 * kMs) {
    master.move_to(step, clock.now());
    tick();
    return run_until([](const fw::GalvoStatus& s) { return s.in_position; }, budget);
  }

  ManualClock clock;
  std::array<int, 2> fds;
  fw::CanPort port;
  fw::Cia402Master master;
  sim::Cia402Twin twin;
  fw::GalvoStatus status;
};

}  // namespace fs::test
