// The hw-sim CiA 402 drive twin at the frame level: NMT, SDO server (values and aborts), state machine,
// heartbeat producer, TPDO, fault injection.
#include <gtest/gtest.h>
#include <linux/can/error.h>
#include <unistd.h>

#include <limits>
#include <optional>

#include "common/cia402_protocol.hpp"
#include "firmware/backends/can_port.hpp"
#include "hw-sim/can/cia402_twin.hpp"
#include "test_clock.hpp"

namespace fs::test {
namespace {

using namespace cia402;

struct TwinRig {
  TwinRig() : fds(fw::CanPort::socketpair_fds()), port(fds[0], true), twin(fds[1], clock) {}
  ~TwinRig() { ::close(fds[1]); }
  void send(const can_frame& f) {
    ASSERT_EQ(::write(fds[0], &f, sizeof f), static_cast<ssize_t>(sizeof f));
    twin.poll();
  }
  std::optional<can_frame> recv_id(std::uint32_t id) {
    can_frame f;
    fw::Nanos ts;
    while (port.recv(f, ts))
      if (f.can_id == id) return f;
    return std::nullopt;
  }
  void drain() {
    can_frame f;
    fw::Nanos ts;
    while (port.recv(f, ts)) {
    }
  }
  // SDO write; returns the response command byte (0x60 ok, 0x80 abort) and the abort code.
  std::pair<std::uint8_t, std::uint32_t> write(std::uint16_t idx, std::uint8_t sub, std::uint32_t v,
                                               std::uint8_t n) {
    drain();
    send(sdo_write(1, idx, sub, v, n));
    auto r = recv_id(kSdoTx + 1);
    EXPECT_TRUE(r.has_value());
    if (!r) return {0, 0};
    EXPECT_EQ(get_u16(r->data + 1), idx);
    return {r->data[0], get_u32(r->data + 4)};
  }
  std::pair<std::uint8_t, std::uint32_t> read(std::uint16_t idx, std::uint8_t sub = 0) {
    drain();
    send(sdo_read(1, idx, sub));
    auto r = recv_id(kSdoTx + 1);
    EXPECT_TRUE(r.has_value());
    if (!r) return {0, 0};
    return {r->data[0], get_u32(r->data + 4)};
  }
  ManualClock clock;
  std::array<int, 2> fds;
  fw::CanPort port;
  sim::Cia402Twin twin;
};

TEST(Cia402Twin, SendsBootUpAndStartsPreOperational) {
  TwinRig r;
  auto f = r.recv_id(kHeartbeat + 1);
  ASSERT_TRUE(f);
  EXPECT_EQ(f->len, 1);
  EXPECT_EQ(f->data[0], kStateBoot);
  EXPECT_EQ(r.twin.nmt_state(), kStatePreOperational);
  r.send(nmt(kNmtStart, 1));
  EXPECT_EQ(r.twin.nmt_state(), kStateOperational);
  r.send(nmt(kNmtStop, 0));  // broadcast
  EXPECT_EQ(r.twin.nmt_state(), kStateStopped);
  r.send(nmt(kNmtStart, 2));  // other node
  EXPECT_EQ(r.twin.nmt_state(), kStateStopped);
}

TEST(Cia402Twin, SdoServerReadsWritesAndAborts) {
  TwinRig r;
  EXPECT_EQ(r.write(kProfileVelocity, 0, 777, 4), std::make_pair(kSdoWriteResp, 0u));
  auto [cmd, v] = r.read(kProfileVelocity);
  EXPECT_EQ(cmd, 0x43);  // expedited, 4 bytes
  EXPECT_EQ(v, 777u);
  EXPECT_EQ(r.write(kModesOfOperation, 0, 1, 1).first, kSdoWriteResp);
  std::tie(cmd, v) = r.read(kModesDisplay);
  EXPECT_EQ(cmd, 0x4F);  // 1 byte
  EXPECT_EQ(v, 1u);
  std::tie(cmd, v) = r.read(kStatusword);
  EXPECT_EQ(cmd, 0x4B);  // 2 bytes
  EXPECT_EQ(decode_state(static_cast<std::uint16_t>(v)), DriveState::SwitchOnDisabled);

  EXPECT_EQ(r.write(0x2000, 0, 1, 4), std::make_pair(kSdoAbort, kAbortNoObject));
  EXPECT_EQ(r.write(kStatusword, 0, 1, 2), std::make_pair(kSdoAbort, kAbortReadOnly));
  EXPECT_EQ(r.write(kProfileVelocity, 0, 1, 2), std::make_pair(kSdoAbort, kAbortLength));
  EXPECT_EQ(r.write(kModesOfOperation, 0, 3, 1), std::make_pair(kSdoAbort, kAbortRange));
  EXPECT_EQ(r.write(kHomingMethod, 0, 1, 1), std::make_pair(kSdoAbort, kAbortRange));
  EXPECT_EQ(r.write(kProfileAcceleration, 0, 0, 4), std::make_pair(kSdoAbort, kAbortRange));
  EXPECT_EQ(r.write(kTpdo1Comm, 1, 0, 2), std::make_pair(kSdoAbort, kAbortNoObject));
  EXPECT_EQ(r.read(0x1234).first, kSdoAbort);
  // a segmented (non-expedited) download is refused
  can_frame seg = sdo_write(1, kProfileVelocity, 0, 0, 4);
  seg.data[0] = 0x21;
  r.drain();
  r.send(seg);
  auto a = r.recv_id(kSdoTx + 1);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->data[0], kSdoAbort);
  EXPECT_EQ(get_u32(a->data + 4), kAbortCommand);
  EXPECT_EQ(r.twin.stats().sdo_aborts, 9u);
}

TEST(Cia402Twin, ControlwordStateMachine) {
  TwinRig r;
  auto state = [&] { return decode_state(static_cast<std::uint16_t>(r.read(kStatusword).second)); };
  EXPECT_EQ(state(), DriveState::SwitchOnDisabled);
  r.write(kControlword, 0, kCwSwitchOn, 2);  // 07h from switch-on-disabled: not allowed
  EXPECT_EQ(state(), DriveState::SwitchOnDisabled);
  r.write(kControlword, 0, kCwShutdown, 2);
  EXPECT_EQ(state(), DriveState::ReadyToSwitchOn);
  r.write(kControlword, 0, kCwSwitchOn, 2);
  EXPECT_EQ(state(), DriveState::SwitchedOn);
  r.write(kControlword, 0, kCwEnableOperation, 2);
  EXPECT_EQ(state(), DriveState::OperationEnabled);
  r.write(kControlword, 0, 0x0002, 2);  // quick stop
  r.clock.advance(10 * kMs);
  r.twin.poll();
  EXPECT_EQ(state(), DriveState::SwitchOnDisabled);
  r.twin.inject_drive_fault(0x5530);
  EXPECT_EQ(state(), DriveState::Fault);
  EXPECT_EQ(r.read(kErrorCode).second, 0x5530u);
  r.write(kControlword, 0, kCwFaultReset, 2);
  EXPECT_EQ(state(), DriveState::SwitchOnDisabled);
  EXPECT_EQ(r.read(kErrorCode).second, 0u);
}

TEST(Cia402Twin, HeartbeatProducerRunsAtTheConfiguredPeriod) {
  TwinRig r;
  r.write(kHeartbeatProducer, 0, 20, 2);
  r.drain();
  int n = 0;
  for (int i = 0; i < 1000; ++i) {
    r.clock.advance(kMs);
    r.twin.poll();
    while (r.recv_id(kHeartbeat + 1)) ++n;
  }
  EXPECT_EQ(n, 50);  // 1 s / 20 ms
  r.twin.set_heartbeat_loss(true);
  for (int i = 0; i < 200; ++i) {
    r.clock.advance(kMs);
    r.twin.poll();
  }
  EXPECT_FALSE(r.recv_id(kHeartbeat + 1));
}

TEST(Cia402Twin, TpdoCarriesStatuswordAndPositionOnChangeAndOnTheEventTimer) {
  sim::Cia402TwinConfig cfg;
  cfg.start_position = -42;
  ManualClock clock;
  auto fds = fw::CanPort::socketpair_fds();
  fw::CanPort port(fds[0], true);
  sim::Cia402Twin twin(fds[1], clock, cfg);
  auto send = [&](const can_frame& f) { ASSERT_EQ(::write(fds[0], &f, sizeof f), 16); };
  send(nmt(kNmtStart, 1));
  send(sdo_write(1, kTpdo1Comm, 5, 10, 2));
  twin.poll();
  can_frame f;
  fw::Nanos ts;
  int tpdos = 0;
  std::int32_t pos = 0;
  for (int i = 0; i < 100; ++i) {
    clock.advance(kMs);
    twin.poll();
    while (port.recv(f, ts))
      if (f.can_id == kTpdo1 + 1) {
        ++tpdos;
        pos = static_cast<std::int32_t>(get_u32(f.data + 2));
      }
  }
  EXPECT_GE(tpdos, 10);
  EXPECT_LE(tpdos, 12);
  EXPECT_EQ(pos, -42);
  ::close(fds[1]);
}

TEST(Cia402Twin, BusOffSendsErrorFramesAndRestarts) {
  TwinRig r;
  r.drain();
  r.twin.inject_bus_off(50 * kMs);
  auto f = r.recv_id(CAN_ERR_FLAG | CAN_ERR_BUSOFF);
  ASSERT_TRUE(f);
  // mute while bus-off
  r.send(sdo_read(1, kStatusword, 0));
  EXPECT_FALSE(r.recv_id(kSdoTx + 1));
  r.clock.advance(60 * kMs);
  r.twin.poll();
  EXPECT_TRUE(r.recv_id(CAN_ERR_FLAG | CAN_ERR_RESTARTED));
  EXPECT_EQ(r.read(kStatusword).first, 0x4B);
}

TEST(Cia402Twin, ScheduledFaultsRunAtTheirTime) {
  TwinRig r;
  const fw::Nanos t0 = r.clock.now();
  r.twin.schedule(t0 + 30 * kMs, [](sim::Cia402Twin& t) { t.inject_drive_fault(0x7300); });
  r.clock.advance(29 * kMs);
  r.twin.poll();
  EXPECT_NE(r.twin.state(), DriveState::Fault);
  r.clock.advance(1 * kMs);
  r.twin.poll();
  EXPECT_EQ(r.twin.state(), DriveState::Fault);
  auto e = r.recv_id(kEmcy + 1);
  ASSERT_TRUE(e);
  EXPECT_EQ(get_u16(e->data), 0x7300);
}

TEST(Cia402Twin, MalformedFramesAreCountedNotFatal) {
  TwinRig r;
  can_frame f = make_frame(kSdoRx + 1, 3);  // short SDO
  r.send(f);
  f = make_frame(kRpdo1 + 1, 2);
  r.send(nmt(kNmtStart, 1));
  r.send(f);  // short RPDO
  f = make_frame(kSdoRx + 1, 8);
  f.len = 200;  // invalid length
  r.send(f);
  EXPECT_EQ(r.twin.stats().bad_frames, 3u);
  EXPECT_EQ(r.read(kStatusword).first, 0x4B);
}

// Relative set-points add to the last target; one that would pass the int32 range saturates (the sum was an
// int32 overflow, undefined behaviour, for any master sending large relative targets).
TEST(Cia402Twin, RelativeSetPointsSaturateAtTheInt32Range) {
  TwinRig r;
  r.write(kModesOfOperation, 0, static_cast<std::uint8_t>(kModeProfilePosition), 1);
  r.write(kControlword, 0, kCwShutdown, 2);
  r.write(kControlword, 0, kCwSwitchOn, 2);
  r.write(kControlword, 0, kCwEnableOperation, 2);
  auto set_point = [&](std::int32_t target, std::uint16_t extra) {
    r.write(kTargetPosition, 0, static_cast<std::uint32_t>(target), 4);
    r.write(kControlword, 0, kCwEnableOperation | kCwNewSetPoint | extra, 2);
    r.write(kControlword, 0, kCwEnableOperation, 2);
  };
  set_point(2'000'000'000, 0);
  EXPECT_EQ(r.twin.target(), 2'000'000'000);
  set_point(500, kCwRelative);
  EXPECT_EQ(r.twin.target(), 2'000'000'500);
  set_point(2'000'000'000, kCwRelative);
  EXPECT_EQ(r.twin.target(), std::numeric_limits<std::int32_t>::max());
  set_point(-2'000'000'000, 0);
  set_point(-2'000'000'000, kCwRelative);
  EXPECT_EQ(r.twin.target(), std::numeric_limits<std::int32_t>::min());
}

}  // namespace
}  // namespace fs::test
