// Device twins: mirror dynamics, stepper lines (edges, rate limit, home switch), laser log, camera queue
// semantics, and every injected fault.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "common/error.hpp"
#include "firmware/extract/stripe_extractor.hpp"
#include "hw-sim/sim_camera.hpp"
#include "hw-sim/sim_clock.hpp"
#include "hw-sim/sim_faults.hpp"
#include "hw-sim/sim_laser.hpp"
#include "hw-sim/sim_mirror.hpp"
#include "hw-sim/sim_stepper.hpp"
#include "hw-sim/table_renderer.hpp"

namespace fs::sim {
namespace {

constexpr fw::Nanos kMs = 1'000'000;

TEST(Mirror, SettlesWithoutOvershootAndRemembersHistory) {
  SimMirror m(0.0, 100'000);
  m.command(0, 1.0);
  EXPECT_NEAR(m.position_at(0), 0.0, 1e-12);
  EXPECT_GT(m.position_at(100'000), 0.2);
  EXPECT_LT(m.position_at(100'000), 0.8);
  double prev = 0.0;
  for (fw::Nanos t = 0; t < 2 * kMs; t += 10'000) {
    const double x = m.position_at(t);
    EXPECT_LE(x, 1.0 + 1e-9);
    EXPECT_GE(x + 1e-12, prev);
    prev = x;
  }
  EXPECT_TRUE(m.settled_at(kMs, 0.01));
  EXPECT_FALSE(m.settled_at(200'000, 0.01));
  m.command(5 * kMs, 2.0);
  EXPECT_NEAR(m.position_at(3 * kMs), 1.0, 1e-6);  // from the history
  EXPECT_NEAR(m.position_at(9 * kMs), 2.0, 1e-6);
  // Velocity is continuous across a command issued mid-motion.
  SimMirror v(0.0, 100'000);
  v.command(0, 10.0);
  const double before = v.velocity_at(50'000);
  v.command(50'000, 20.0);
  EXPECT_NEAR(v.velocity_at(50'000), before, 1e-6 * std::abs(before));
}

TEST(Stepper, CountsEdgesFollowsDirAndEnforcesRate) {
  SimMirror m(0.0);
  StepperTwinParams p;
  p.start_position = 10;
  p.home_position = 0;
  SimStepperLines lines(m, nullptr, p);
  fw::Nanos t = 0;
  lines.set_step(true, t);  // disabled: ignored
  lines.set_step(false, t);
  EXPECT_EQ(lines.motor_position(), 10);
  lines.set_enable(true, t);
  lines.set_dir(true, t);
  for (int i = 0; i < 5; ++i) {
    t += 100'000;
    lines.set_step(true, t);
    lines.set_step(false, t);
  }
  EXPECT_EQ(lines.motor_position(), 15);
  // Too fast: the second pulse within min_step_interval is lost.
  t += 100'000;
  lines.set_step(true, t);
  lines.set_step(false, t);
  lines.set_step(true, t + 1000);
  lines.set_step(false, t + 1000);
  EXPECT_EQ(lines.motor_position(), 16);
  EXPECT_EQ(lines.rate_violations(), 1u);
  ASSERT_EQ(lines.step_log().size(), 7u);
  EXPECT_EQ(lines.step_log().back().direction, 0);
  EXPECT_EQ(lines.step_log().back().t, t + 1000);
  // Mirror follows the motor.
  EXPECT_NEAR(m.position_at(t + 5 * kMs), 16.0, 1e-6);
  double pos = 0;
  ASSERT_TRUE(lines.read_position(pos, t + 5 * kMs));
  EXPECT_NEAR(pos, 16.0, 1.0 / 64);
}

TEST(Stepper, HomeSwitchEdges) {
  SimMirror m(0.0);
  StepperTwinParams p;
  p.start_position = 2;
  p.home_position = 0;
  SimStepperLines lines(m, nullptr, p);
  lines.set_enable(true, 0);
  lines.set_dir(false, 0);
  fw::Nanos t = 0;
  EXPECT_FALSE(lines.read_home(t));
  fw::GpioEdge e;
  for (int i = 0; i < 3; ++i) {
    t += 100'000;
    lines.set_step(true, t);
    lines.set_step(false, t);
  }
  EXPECT_TRUE(lines.read_home(t));
  ASSERT_TRUE(lines.next_home_edge(e));
  EXPECT_TRUE(e.rising);
  EXPECT_EQ(e.timestamp, 200'000);  // the step to position 0
  EXPECT_FALSE(lines.next_home_edge(e));
  lines.set_dir(true, t);
  for (int i = 0; i < 2; ++i) {
    t += 100'000;
    lines.set_step(true, t);
    lines.set_step(false, t);
  }
  ASSERT_TRUE(lines.next_home_edge(e));
  EXPECT_FALSE(e.rising);
}

TEST(Stepper, FaultMissedStepsStallAndHomeStuck) {
  {
    FaultScript f;
    f.add(parse_fault_spec("galvo.missed-steps@step=3,count=2"));
    SimMirror m(0.0);
    StepperTwinParams p;
    p.start_position = 0;
    SimStepperLines lines(m, &f, p);
    lines.set_enable(true, 0);
    lines.set_dir(true, 0);
    for (int i = 0; i < 10; ++i) {
      lines.set_step(true, (i + 1) * 100'000);
      lines.set_step(false, (i + 1) * 100'000);
    }
    EXPECT_EQ(lines.motor_position(), 8);
    EXPECT_EQ(lines.lost_steps(), 2u);
    EXPECT_EQ(f.fired_at(0), 300'000);
  }
  {
    FaultScript f;
    f.add(parse_fault_spec("galvo.stall@t=0.0005"));
    SimMirror m(0.0);
    StepperTwinParams p;
    p.start_position = 0;
    SimStepperLines lines(m, &f, p);
    lines.set_enable(true, 0);
    lines.set_dir(true, 0);
    for (int i = 0; i < 10; ++i) {
      lines.set_step(true, (i + 1) * 100'000);
      lines.set_step(false, (i + 1) * 100'000);
    }
    EXPECT_EQ(lines.motor_position(), 4);  // pulses at 0.1 .. 0.4 ms moved it
    EXPECT_NEAR(m.position_at(5 * kMs), 4.0, 1e-6);
  }
  {
    FaultScript f;
    f.add(parse_fault_spec("galvo.home-stuck"));
    SimMirror m(0.0);
    StepperTwinParams p;
    p.start_position = 1;
    p.home_position = 0;
    SimStepperLines lines(m, &f, p);
    lines.set_enable(true, 0);
    lines.set_dir(false, 0);
    for (int i = 0; i < 5; ++i) {
      lines.set_step(true, (i + 1) * 100'000);
      lines.set_step(false, (i + 1) * 100'000);
    }
    fw::GpioEdge e;
    EXPECT_FALSE(lines.read_home(kMs));
    EXPECT_FALSE(lines.next_home_edge(e));
  }
}

TEST(Laser, LogsCommandsAndStuckLine) {
  FaultScript f;
  f.add(parse_fault_spec("laser.stuck@on=1"));
  SimLaser l(&f);
  l.set(true, 100);
  l.set(false, 200);
  EXPECT_FALSE(l.emitting());
  l.set(true, 300);  // second switch-on (index 1): stuck on from here
  l.set(false, 400);
  EXPECT_FALSE(l.is_on());
  EXPECT_TRUE(l.emitting());
  bool em = false;
  ASSERT_TRUE(l.monitor(em));
  EXPECT_TRUE(em);
  l.force_off();
  EXPECT_TRUE(l.emitting());
  ASSERT_EQ(l.log().size(), 5u);
  EXPECT_TRUE(l.log().back().forced);
  EXPECT_TRUE(l.emitting_at(150));
  EXPECT_FALSE(l.emitting_at(250));
  EXPECT_NEAR(l.on_fraction(100, 300), 0.5, 1e-12);
  EXPECT_NEAR(l.on_fraction(0, 100), 0.0, 1e-12);
}

struct CameraFixture {
  explicit CameraFixture(std::vector<std::string> faults = {}, std::uint32_t buffers = 4)
      : cal(small_cal()), renderer(cal), clock(0), mirror(250.0) {
    for (auto& s : faults) script.add(parse_fault_spec(s));
    laser = std::make_unique<SimLaser>(&script);
    CameraTwinParams p;
    p.frame_period = 10 * kMs;
    p.exposure = 2 * kMs;
    p.readout = kMs;
    p.buffers = buffers;
    cam = std::make_unique<SimCamera>(clock, mirror, *laser, renderer, &script, p);
  }
  static ScannerCalibration small_cal() {
    ScannerCalibration c = ScannerCalibration::bench_default(500);
    c.camera.width = 320;
    c.camera.height = 256;
    c.camera.fx = c.camera.fy = 400.0;
    c.camera.cx = 159.5;
    c.camera.cy = 127.5;
    return c;
  }
  ScannerCalibration cal;
  TableStripeRenderer renderer;
  SimClock clock;
  SimMirror mirror;
  FaultScript script;
  std::unique_ptr<SimLaser> laser;
  std::unique_ptr<SimCamera> cam;
};

TEST(Camera, SequenceTimestampsAndNonBlockingGrab) {
  CameraFixture fx;
  fx.cam->start(0);
  fw::FrameView f;
  EXPECT_EQ(fx.cam->grab(0, f), fw::GrabResult::Timeout);  // deadline = now: does not wait
  EXPECT_EQ(fx.clock.now(), 0);
  EXPECT_EQ(fx.cam->grab(2 * kMs, f), fw::GrabResult::Timeout);  // first frame ready at 3 ms
  EXPECT_EQ(fx.clock.now(), 2 * kMs);
  ASSERT_EQ(fx.cam->grab(50 * kMs, f), fw::GrabResult::Ok);
  EXPECT_EQ(fx.clock.now(), 3 * kMs);  // slept until the frame was ready
  EXPECT_EQ(f.sequence, 0u);
  EXPECT_EQ(f.timestamp, 0);
  EXPECT_EQ(f.width, 320u);
  fx.cam->release(f);
  ASSERT_EQ(fx.cam->grab(50 * kMs, f), fw::GrabResult::Ok);
  EXPECT_EQ(f.sequence, 1u);
  EXPECT_EQ(f.timestamp, 10 * kMs);
  fx.cam->release(f);
  EXPECT_EQ(fx.cam->frames_dropped(), 0u);
}

TEST(Camera, DropsFramesWhenAllBuffersAreBusy) {
  CameraFixture fx({}, 2);
  fx.cam->start(0);
  fx.clock.sleep_until(100 * kMs);  // 10 frames done, only 2 buffers
  fw::FrameView a, b, c;
  ASSERT_EQ(fx.cam->grab(fx.clock.now(), a), fw::GrabResult::Ok);
  ASSERT_EQ(fx.cam->grab(fx.clock.now(), b), fw::GrabResult::Ok);
  EXPECT_EQ(a.sequence, 0u);
  EXPECT_EQ(b.sequence, 1u);
  EXPECT_EQ(fx.cam->frames_dropped(), 8u);
  fx.cam->release(a);
  fx.cam->release(b);
  ASSERT_EQ(fx.cam->grab(fx.clock.now() + 20 * kMs, c), fw::GrabResult::Ok);
  EXPECT_EQ(c.sequence, 10u);  // gap 2..9
  fx.cam->release(c);
}

TEST(Camera, RendersForMirrorAndLaserAtExposureTime) {
  CameraFixture fx;
  fx.cam->start(0);
  // Laser on only for frame 1's exposure [10, 12] ms; mirror moves to 260 at 5 ms (settled long before 10).
  fx.mirror.command(5 * kMs, 260.0);
  fx.laser->set(true, 9 * kMs);
  fx.laser->set(false, 13 * kMs);
  fw::FrameView f0, f1;
  std::vector<msg::StripePoint> pts(256);
  ASSERT_EQ(fx.cam->grab(100 * kMs, f0), fw::GrabResult::Ok);
  const auto c0 = fw::extract_frame(f0, fw::ExtractParams{}, pts);
  EXPECT_EQ(c0.points, 0u);  // laser off during frame 0
  fx.cam->release(f0);
  ASSERT_EQ(fx.cam->grab(100 * kMs, f1), fw::GrabResult::Ok);
  const auto c1 = fw::extract_frame(f1, fw::ExtractParams{}, pts);
  EXPECT_GT(c1.points, 200u);
  std::vector<double> truth(256);
  fx.renderer.truth(260.0, truth);
  double err = 0.0;
  for (std::uint32_t i = 0; i < c1.points; ++i) err += std::abs(pts[i].col - truth[pts[i].row]);
  EXPECT_LT(err / c1.points, 0.1);
  const FrameRecord* rec = fx.cam->find(1);
  ASSERT_NE(rec, nullptr);
  EXPECT_NEAR(rec->mirror_step, 260.0, 1e-6);
  EXPECT_NEAR(rec->laser_fraction, 1.0, 1e-12);
  fx.cam->release(f1);
}

TEST(Camera, FaultTimeoutDropAndSaturate) {
  {
    CameraFixture fx({"camera.drop@frame=1,count=2"});
    fx.cam->start(0);
    fw::FrameView f;
    std::vector<std::uint32_t> seqs;
    for (int i = 0; i < 3; ++i) {
      ASSERT_EQ(fx.cam->grab(fx.clock.now() + 100 * kMs, f), fw::GrabResult::Ok);
      seqs.push_back(f.sequence);
      fx.cam->release(f);
    }
    EXPECT_EQ(seqs, (std::vector<std::uint32_t>{0, 3, 4}));
    EXPECT_EQ(fx.cam->frames_dropped(), 2u);
  }
  {
    CameraFixture fx({"camera.timeout@t=0.015"});
    fx.cam->start(0);
    fw::FrameView f;
    ASSERT_EQ(fx.cam->grab(100 * kMs, f), fw::GrabResult::Ok);
    fx.cam->release(f);
    ASSERT_EQ(fx.cam->grab(100 * kMs, f), fw::GrabResult::Ok);  // exposed at 10 ms, before the fault
    fx.cam->release(f);
    EXPECT_EQ(fx.cam->grab(100 * kMs, f), fw::GrabResult::Timeout);
    EXPECT_EQ(fx.clock.now(), 100 * kMs);
  }
  {
    CameraFixture fx({"camera.saturate@frame=0"});
    fx.laser->set(true, 0);
    fx.cam->start(0);
    fw::FrameView f;
    ASSERT_EQ(fx.cam->grab(100 * kMs, f), fw::GrabResult::Ok);
    std::vector<msg::StripePoint> pts(256);
    const auto c = fw::extract_frame(f, fw::ExtractParams{}, pts);
    EXPECT_GT(c.saturated, 200u);
    fx.cam->release(f);
    ASSERT_EQ(fx.cam->grab(100 * kMs, f), fw::GrabResult::Ok);  // count=1: the next one is normal
    EXPECT_EQ(fw::extract_frame(f, fw::ExtractParams{}, pts).saturated, 0u);
    fx.cam->release(f);
  }
}

TEST(FaultSpec, ParsesAndRejects) {
  const FaultSpec a = parse_fault_spec("camera.drop@frame=40,count=2");
  EXPECT_EQ(a.kind, FaultKind::CameraDrop);
  EXPECT_EQ(a.trigger, FaultTrigger::Frame);
  EXPECT_EQ(a.at, 40);
  EXPECT_EQ(a.count, 2);
  const FaultSpec b = parse_fault_spec("laser.stuck@t=1.5,for=0.25,level=off");
  EXPECT_EQ(b.trigger, FaultTrigger::Time);
  EXPECT_EQ(b.at, 1'500'000'000);
  EXPECT_EQ(b.duration, 250'000'000);
  EXPECT_FALSE(b.level);
  EXPECT_EQ(parse_fault_spec("galvo.missed-steps").count, 3);
  for (const char* bad : {"", "galvo", "galvo.melt", "galvo.stall@frame=3", "camera.drop@frame=-1",
                          "camera.drop@frame=x", "laser.stuck,level=maybe", "galvo.stall@t=nan",
                          "galvo.stall,x", "galvo.stall,colour=red", "galvo.stall@t"}) {
    EXPECT_THROW(parse_fault_spec(bad), fs::Error) << bad;
  }
  try {
    parse_fault_spec("camera.drop@frame=x");
  } catch (const fs::Error& e) {
    EXPECT_NE(std::string(e.what()).find("camera.drop@frame=x"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("frame"), std::string::npos);
  }
}

}  // namespace
}  // namespace fs::sim
