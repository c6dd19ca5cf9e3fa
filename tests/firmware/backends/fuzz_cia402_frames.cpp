// Fuzz target: arbitrary CAN frames (16-byte struct can_frame records) into the CiA 402 master and the drive
// twin, interleaved with commands. Nothing may crash, hang or trip a sanitizer.
#include <unistd.h>

#include <cstdint>
#include <cstring>

#include "firmware/backends/can_port.hpp"
#include "firmware/backends/cia402_master.hpp"
#include "hw-sim/can/cia402_twin.hpp"
#include "test_clock.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace fs;
  test::ManualClock clock;
  auto fds = fw::CanPort::socketpair_fds();
  fw::CanPort port(fds[0], true);
  fw::Cia402Config cfg;
  fw::Cia402Master master(port, cfg);
  // a second pair feeds junk to the twin directly
  auto fds2 = fw::CanPort::socketpair_fds();
  sim::Cia402Twin twin(fds[1], clock);
  sim::Cia402Twin twin2(fds2[1], clock);
  master.enable(clock.now());
  for (std::size_t off = 0; off + 17 <= size; off += 17) {
    can_frame f;
    std::memcpy(&f, data + off + 1, sizeof f);
    const std::uint8_t op = data[off];
    switch (op % 8) {
      case 0:
        master.move_to(static_cast<std::int32_t>(f.can_id), clock.now());
        break;
      case 1:
        master.reset_fault(clock.now());
        break;
      case 2:
        master.start_homing(clock.now());
        break;
      default:
        break;
    }
    if (op & 0x80)
      (void)::write(fds[1], &f, sizeof f);  // to the master
    else
      (void)::write(fds2[0], &f, sizeof f);  // to twin2
    clock.advance(test::kMs * (1 + (op & 0x0F)));
    twin.poll();
    twin2.poll();
    (void)master.poll(clock.now());
  }
  ::close(fds[1]);
  ::close(fds2[0]);
  ::close(fds2[1]);
  return 0;
}
