// The controller loop on the hw-sim twins with virtual time (hardware in the loop): a clean scan of the
// table (stripes vs. ground truth, no frame lost, interlock clean, zero allocations per tick), and each
// injected fault ending in its documented state with the laser off and a Fault message.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "common/alloc_counter/alloc_counter.hpp"
#include "hil_support.hpp"

namespace fs::test {
namespace {

using fw::FaultCode;
using fw::State;

// Interlock checks from the twins' logs.
// 1. The laser never emits while a step pulse moves the mirror.
// 2. Whenever the laser came on, the mirror was settled on an integer step.
void expect_interlock_clean(Hil& h) {
  for (const auto& e : h.rig.lines.step_log()) {
    if (e.direction == 0) continue;
    EXPECT_FALSE(h.rig.laser.emitting_at(e.t)) << "laser on during a step at t=" << e.t;
  }
  for (const auto& ev : h.rig.laser.log()) {
    if (!ev.commanded || ev.forced) continue;
    const double x = h.rig.mirror.position_at(ev.t);
    EXPECT_NEAR(x, std::round(x), 0.02) << "laser on while the mirror moved, t=" << ev.t;
  }
  EXPECT_FALSE(h.rig.laser.log_overflow());
}

// The laser (physically) off from fault_time + one period on, and not commanded on after the fault.
void expect_laser_off_after(Hil& h, fw::Nanos t) {
  const fw::Nanos limit = t + h.ctl->config().period;
  for (const auto& ev : h.rig.laser.log()) {
    if (ev.t > t) {
      EXPECT_FALSE(ev.commanded) << "laser commanded on after the fault at " << ev.t;
    }
  }
  EXPECT_FALSE(h.rig.laser.emitting_at(limit));
  EXPECT_FALSE(h.rig.laser.emitting());
}

TEST(Controller, CleanScanMatchesGroundTruthWithoutAllocations) {
  Hil h(60);
  h.ctl->start();
  // Warm-up: homing (the first ticks may touch lazily initialised state).
  for (int i = 0; i < 5; ++i) h.ctl->run_one();
  AllocCounter allocs;
  h.ctl->loop();
  EXPECT_EQ(allocs.allocations(), 0u) << "heap allocations in the loop thread during the scan";
  h.ctl->finish();
  const auto& r = h.ctl->report();
  ASSERT_EQ(r.state, State::Done) << fw::to_string(r.fault);
  EXPECT_EQ(r.stripes_sent, 60u);
  EXPECT_EQ(r.frames_dropped, 0u);
  EXPECT_EQ(r.overruns, 0u);
  EXPECT_GT(r.lateness.count(), 100u);

  const Decoded d = h.decoded();
  EXPECT_EQ(d.scan_begins, 1);
  ASSERT_EQ(d.stripes.size(), 60u);
  ASSERT_EQ(d.ends.size(), 1u);
  EXPECT_EQ(d.ends[0].completed, 1);
  EXPECT_EQ(d.ends[0].stripes_sent, 60u);
  EXPECT_EQ(d.ends[0].frames_dropped, 0u);
  EXPECT_EQ(d.ends[0].loop.overruns, 0u);
  EXPECT_TRUE(d.faults.empty());
  for (const auto& f : d.faults) ADD_FAILURE() << "fault " << f.code << ": " << f.text;
  std::vector<double> truth(h.cal.camera.height);
  double err_sum = 0.0;
  std::size_t n = 0;
  std::uint32_t prev_seq = 0;
  for (std::size_t i = 0; i < d.stripes.size(); ++i) {
    const auto& s = d.stripes[i];
    EXPECT_EQ(s.step_index, i);
    if (i > 0) {
      EXPECT_GT(s.frame_sequence, prev_seq);
    }
    prev_seq = s.frame_sequence;
    EXPECT_NEAR(s.measured_position, static_cast<double>(i), 0.05);
    EXPECT_NEAR(s.commanded_angle, h.cal.laser.mirror_angle(static_cast<double>(i)), 1e-12);
    const sim::FrameRecord* rec = h.rig.camera.find(s.frame_sequence);
    ASSERT_NE(rec, nullptr);
    EXPECT_EQ(rec->exposure_start, s.capture_time_ns);
    EXPECT_NEAR(rec->mirror_step, static_cast<double>(i), 0.01);  // exposed at the commanded step
    EXPECT_LT(rec->mirror_travel, 0.01);
    EXPECT_NEAR(rec->laser_fraction, 1.0, 1e-9);  // laser on for the whole exposure
    h.renderer.truth(static_cast<double>(i), truth);
    std::size_t visible = 0;
    for (double c : truth) visible += std::isfinite(c) ? 1 : 0;
    EXPECT_EQ(d.points[i].size(), visible) << "step " << i;
    for (const auto& p : d.points[i]) {
      ASSERT_TRUE(std::isfinite(truth[p.row]));
      err_sum += std::abs(p.col - truth[p.row]);
      ++n;
    }
  }
  ASSERT_GT(n, 0u);
  EXPECT_LE(err_sum / n, 0.05) << "mean |col - truth| over " << n << " points";
  expect_interlock_clean(h);
  // Every stripe's frame: no sequence gaps over the whole run.
  EXPECT_EQ(h.rig.camera.frames_dropped(), 0u);
}

struct FaultCase {
  const char* spec;
  State state;
  FaultCode code;  // fatal code, or the warning expected in a Fault message
  bool physical_off = true;
};

class ControllerFault : public ::testing::TestWithParam<FaultCase> {};

TEST_P(ControllerFault, EndsInDocumentedStateWithLaserOff) {
  const FaultCase fc = GetParam();
  Hil h(40, {fc.spec});
  const auto& r = h.ctl->run();
  EXPECT_EQ(r.state, fc.state) << fc.spec << ": " << fw::to_string(r.fault);
  const Decoded d = h.decoded();
  ASSERT_EQ(d.ends.size(), 1u);
  bool found = false;
  for (const auto& f : d.faults) found = found || f.code == static_cast<std::uint32_t>(fc.code);
  EXPECT_TRUE(found) << fc.spec << ": no Fault message with code " << static_cast<int>(fc.code);
  EXPECT_FALSE(h.rig.laser.is_on());
  if (fc.state == State::Fault) {
    EXPECT_EQ(r.fault, fc.code) << fw::to_string(r.fault);
    EXPECT_EQ(d.ends[0].completed, 0);
    EXPECT_EQ(d.ends[0].last_fault_code, static_cast<std::uint32_t>(fc.code));
    EXPECT_LT(d.stripes.size(), 40u);
    if (fc.physical_off) expect_laser_off_after(h, r.fault_time);
    EXPECT_FALSE(h.rig.lines.enabled());  // galvo disabled
  } else {
    EXPECT_EQ(d.ends[0].completed, 1);
    EXPECT_EQ(d.stripes.size(), 40u);
    for (std::size_t i = 0; i < d.stripes.size(); ++i) EXPECT_EQ(d.stripes[i].step_index, i);
  }
  if (fc.physical_off) {
    EXPECT_FALSE(h.rig.laser.emitting());
    expect_interlock_clean(h);
  }
}

INSTANTIATE_TEST_SUITE_P(
    Faults, ControllerFault,
    ::testing::Values(FaultCase{"galvo.stall@step=20", State::Fault, FaultCode::GalvoStall},
                      FaultCase{"galvo.missed-steps@step=-10,count=3", State::Fault,
                                FaultCode::GalvoMissedSteps},
                      FaultCase{"galvo.home-stuck", State::Fault, FaultCode::HomeNotFound},
                      FaultCase{"galvo.home-stuck,level=on", State::Fault, FaultCode::HomeNotFound},
                      FaultCase{"camera.timeout@t=0.1", State::Fault, FaultCode::CameraTimeout},
                      FaultCase{"camera.drop@frame=30,count=2", State::Done, FaultCode::FramesDropped},
                      FaultCase{"camera.saturate@frame=30", State::Done, FaultCode::SaturatedRetry},
                      FaultCase{"camera.saturate@frame=30,count=20", State::Fault, FaultCode::FrameSaturated},
                      FaultCase{"laser.stuck@on=10", State::Fault, FaultCode::LaserMonitorMismatch, false}),
    [](const ::testing::TestParamInfo<FaultCase>& i) {
      std::string s = i.param.spec;
      for (auto& ch : s)
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
      return s;
    });

TEST(ControllerInterlock, StuckLaserIsCommandedOffWithinOnePeriod) {
  Hil h(40, {"laser.stuck@on=10"});
  const auto& r = h.ctl->run();
  ASSERT_EQ(r.fault, FaultCode::LaserMonitorMismatch);
  // The line stays physically on (that is the fault), but the command went off by the next period and the
  // fault was raised in the tick that saw the mismatch.
  fw::Nanos stuck_at = -1;
  for (const auto& ev : h.rig.laser.log())
    if (!ev.commanded && ev.emitting && stuck_at < 0) stuck_at = ev.t;
  ASSERT_GE(stuck_at, 0);
  EXPECT_LE(r.fault_time - stuck_at, h.ctl->config().period);
  EXPECT_FALSE(h.rig.laser.is_on());
}

TEST(ControllerInterlock, DwellOverrun) {
  fw::LoopConfig cfg;
  cfg.max_dwell = 2'000'000;  // shorter than the wait for a fresh frame (5 ms period)
  Hil h(20, {}, cfg);
  const auto& r = h.ctl->run();
  ASSERT_EQ(r.state, State::Fault);
  EXPECT_EQ(r.fault, FaultCode::DwellOverrun);
  fw::Nanos on_at = -1;
  for (const auto& ev : h.rig.laser.log()) {
    if (ev.commanded && on_at < 0) on_at = ev.t;
  }
  ASSERT_GE(on_at, 0);
  // Off within one period after the dwell limit.
  EXPECT_FALSE(h.rig.laser.emitting_at(on_at + cfg.max_dwell + cfg.period));
  expect_laser_off_after(h, r.fault_time);
}

TEST(ControllerInterlock, MissedDeadlines) {
  Hil h(40);
  // From 50 ms after start, every wake-up is 400 us late (late_limit 250 us; 4 in a row -> fault).
  const fw::Nanos t0 = h.rig.clock.now();
  h.rig.clock.inject_lateness(t0 + 50'000'000, t0 + 10'000'000'000, 400'000);
  const auto& r = h.ctl->run();
  ASSERT_EQ(r.state, State::Fault);
  EXPECT_EQ(r.fault, FaultCode::DeadlineMissed);
  EXPECT_GE(r.overruns, 4u);
  EXPECT_GE(r.lateness.max(), 400'000);
  expect_laser_off_after(h, r.fault_time);
  // The fault came with the 4th late wake-up in a row.
  EXPECT_LE(r.fault_time, t0 + 50'000'000 + 4 * h.ctl->config().period + 400'000);
}

// A publisher that loses the host after n stripes.
class FlakyHost final : public fw::Publisher {
 public:
  explicit FlakyHost(std::uint32_t n) : n_(n) {}
  void begin(const msg::ScanBegin&) override {}
  bool stripe(const msg::Stripe&) override {
    ++stripes;
    return true;
  }
  void heartbeat(const msg::Heartbeat&) override {}
  void fault(std::uint32_t code, const char*) override { faults.push_back(code); }
  void end(const msg::ScanEnd& e) override { ends.push_back(e); }
  bool host_connected() const override { return stripes < n_; }
  std::uint32_t stripes_dropped() const override { return 0; }
  std::uint32_t stripes = 0;
  std::vector<std::uint32_t> faults;
  std::vector<msg::ScanEnd> ends;

 private:
  std::uint32_t n_;
};

TEST(ControllerInterlock, HostLossWhenRequired) {
  for (bool require : {true, false}) {
    const ScannerCalibration cal = small_calibration(30);
    sim::TableStripeRenderer renderer(cal);
    sim::SimRig rig(renderer);
    FlakyHost host(10);
    fw::LoopConfig cfg;
    cfg.steps = 30;
    cfg.max_rows = cal.camera.height;
    cfg.require_host = require;
    fw::Controller ctl(fw::Devices{rig.clock, rig.galvo, rig.laser, rig.camera}, cfg, host, cal);
    const auto& r = ctl.run();
    if (require) {
      EXPECT_EQ(r.state, State::Fault);
      EXPECT_EQ(r.fault, FaultCode::HostLost);
      EXPECT_EQ(host.stripes, 10u);
      ASSERT_FALSE(host.faults.empty());
      EXPECT_EQ(host.faults.back(), static_cast<std::uint32_t>(FaultCode::HostLost));
      EXPECT_FALSE(rig.laser.emitting_at(r.fault_time + cfg.period));
    } else {
      EXPECT_EQ(r.state, State::Done);
      EXPECT_EQ(host.stripes, 30u);
    }
    ASSERT_EQ(host.ends.size(), 1u);
  }
}

TEST(ControllerInterlock, StopRequest) {
  Hil h(40);
  h.ctl->start();
  for (int i = 0; i < 200; ++i) h.ctl->run_one();
  ASSERT_EQ(h.ctl->state(), State::Scanning);
  h.ctl->request_stop();
  h.ctl->loop();
  h.ctl->finish();
  EXPECT_EQ(h.ctl->report().fault, FaultCode::Stopped);
  expect_laser_off_after(h, h.ctl->report().fault_time);
}

}  // namespace
}  // namespace fs::test
