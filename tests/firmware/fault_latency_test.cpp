// The loop's own measurement of each fault's laser-off latency (FaultEvent, the Fault message text, the
// summary), checked against the laser twin's log: the onset the loop names, whether the line was emitting
// then, and when it went off.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "hil_support.hpp"

namespace fs::test {
namespace {

using fw::FaultCode;
using fw::State;

const fw::FaultEvent& fatal_event(const fw::LoopReport& r) {
  for (std::uint32_t i = 0; i < r.fault_events_n; ++i)
    if (fw::is_fatal(r.fault_events[i].code)) return r.fault_events[i];
  static const fw::FaultEvent none;
  ADD_FAILURE() << "no fatal fault event";
  return none;
}

std::string fault_text(const Decoded& d, FaultCode code) {
  for (const auto& f : d.faults)
    if (f.code == static_cast<std::uint32_t>(code)) return f.text;
  return {};
}

TEST(FaultLatency, DwellOverrunOffWithinOnePeriodOfTheLimit) {
  fw::LoopConfig cfg;
  cfg.max_dwell = 2'300'000;  // between two ticks: the limit passes 0.2 ms before a tick
  Hil h(10, {}, cfg);
  const auto& r = h.ctl->run();
  ASSERT_EQ(r.fault, FaultCode::DwellOverrun);
  const fw::FaultEvent& e = fatal_event(r);
  fw::Nanos on_at = -1;
  for (const auto& ev : h.rig.laser.log())
    if (ev.commanded && on_at < 0) on_at = ev.t;
  ASSERT_GE(on_at, 0);
  EXPECT_EQ(e.onset, on_at + cfg.max_dwell);  // the moment the limit was crossed
  EXPECT_FALSE(e.laser_already_off);
  EXPECT_FALSE(e.laser_still_emitting);
  EXPECT_EQ(e.latency_ns, 200'000);  // the tick after the limit: 2.5 ms after switch-on
  EXPECT_EQ(r.max_laser_off_latency_ns, 200'000);
  // The twin: emitting at the onset, off at onset + latency.
  EXPECT_TRUE(h.rig.laser.emitting_at(e.onset));
  EXPECT_FALSE(h.rig.laser.emitting_at(e.onset + e.latency_ns));
  const Decoded d = h.decoded();
  const std::string text = fault_text(d, FaultCode::DwellOverrun);
  EXPECT_NE(text.find("laser off after 0.20 ms (period 0.50 ms)"), std::string::npos) << text;
  char buf[128];
  fw::format_laser_off(buf, sizeof buf, e, h.ctl->config().period);
  EXPECT_STREQ(buf, "laser off after 0.20 ms (period 0.50 ms)");
}

TEST(FaultLatency, CameraTimeoutWhileExposing) {
  // The camera goes silent while the laser waits for a frame: the fault comes camera_timeout after the last
  // frame; the laser goes off in that tick.
  Hil h(40, {"camera.timeout@t=0.1"});
  const auto& r = h.ctl->run();
  ASSERT_EQ(r.fault, FaultCode::CameraTimeout);
  const fw::FaultEvent& e = fatal_event(r);
  EXPECT_LE(e.onset, r.fault_time);
  EXPECT_GE(e.onset, r.fault_time - h.ctl->config().period);
  EXPECT_FALSE(e.laser_still_emitting);
  if (e.laser_already_off) {
    EXPECT_FALSE(h.rig.laser.emitting_at(e.onset));
  } else {
    EXPECT_TRUE(h.rig.laser.emitting_at(e.onset));
    EXPECT_LE(e.latency_ns, h.ctl->config().period);
    EXPECT_FALSE(h.rig.laser.emitting_at(e.onset + e.latency_ns));
  }
}

TEST(FaultLatency, GalvoStallWithTheLaserAlreadyOff) {
  // A stall is seen while the mirror moves: the laser is off during moves, the loop says so.
  Hil h(40, {"galvo.stall@step=20"});
  const auto& r = h.ctl->run();
  ASSERT_EQ(r.fault, FaultCode::GalvoStall);
  const fw::FaultEvent& e = fatal_event(r);
  EXPECT_TRUE(e.laser_already_off);
  EXPECT_EQ(e.latency_ns, 0);
  EXPECT_EQ(e.step, 20u);
  EXPECT_FALSE(h.rig.laser.emitting_at(e.onset));
  const std::string text = fault_text(h.decoded(), FaultCode::GalvoStall);
  EXPECT_NE(text.find("galvo stall (state scanning, step 20): laser already off"), std::string::npos) << text;
}

TEST(FaultLatency, StuckLineIsReportedStillEmitting) {
  Hil h(40, {"laser.stuck@on=10"});
  const auto& r = h.ctl->run();
  ASSERT_EQ(r.fault, FaultCode::LaserMonitorMismatch);
  const fw::FaultEvent& e = fatal_event(r);
  EXPECT_TRUE(e.laser_still_emitting);
  EXPECT_EQ(e.latency_ns, -1);
  EXPECT_EQ(r.max_laser_off_latency_ns, -1);
  EXPECT_TRUE(h.rig.laser.emitting());
  const std::string text = fault_text(h.decoded(), FaultCode::LaserMonitorMismatch);
  EXPECT_NE(text.find("laser line still emitting after the off command"), std::string::npos) << text;
}

TEST(FaultLatency, LineStuckAtTheLastSwitchOnEndsInFault) {
  // The scan goes Done in the tick that switches the laser off after the last frame; no later tick reads the
  // monitor, so finish() does: a line stuck there is the fault, not a completed scan.
  Hil h(12, {"laser.stuck@on=11"});
  const auto& r = h.ctl->run();
  EXPECT_EQ(r.state, State::Fault);
  EXPECT_EQ(r.fault, FaultCode::LaserMonitorMismatch);
  const Decoded d = h.decoded();
  EXPECT_EQ(d.stripes.size(), 12u);
  ASSERT_EQ(d.ends.size(), 1u);
  EXPECT_EQ(d.ends[0].completed, 0);
  EXPECT_EQ(d.ends[0].last_fault_code, static_cast<std::uint32_t>(FaultCode::LaserMonitorMismatch));
  EXPECT_FALSE(h.rig.laser.is_on());
}

}  // namespace
}  // namespace fs::test
