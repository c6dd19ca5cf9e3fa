// Runs INSIDE the test VM (tests/vm/run_vm.sh), as root, against real kernel drivers: the CiA 402 master
// drives the hw-sim twin over vcan0, GpiodLines (+ the stepper galvo) on a gpio-sim chip read back through
// sysfs, V4l2Camera on v4l2loopback (frames written by this process) and on vivid. Outside the VM every test
// skips.
#include <gtest/gtest.h>
#include <linux/can/error.h>
#include <linux/videodev2.h>
#include <time.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <thread>
#include <vector>

#include "common/error.hpp"
#include "common/messages.hpp"
#include "firmware/backends/factory.hpp"
#include "firmware/backends/gpiod_lines.hpp"
#include "firmware/backends/v4l2_camera.hpp"
#include "firmware/extract/stripe_extractor.hpp"
#include "firmware/galvo/can_galvo.hpp"
#include "firmware/galvo/stepper_galvo.hpp"
#include "firmware/loop/monotonic_clock.hpp"
#include "hw-sim/can/cia402_twin.hpp"
#include "vm_rig.hpp"

namespace fs::vmtest {
namespace {

namespace stdfs = std::filesystem;
using fw::Nanos;
constexpr Nanos kMs = 1'000'000;

bool in_vm() { return std::getenv("FACETSCAN_VM") != nullptr; }
#define REQUIRE_VM() \
  if (!in_vm()) GTEST_SKIP() << "runs only inside the test VM (tests/vm/run_vm.sh)"

using fw::MonotonicClock;

std::string slurp(const stdfs::path& p) {
  std::ifstream in(p);
  std::string s;
  std::getline(in, s);
  return s;
}
void put(const stdfs::path& p, const std::string& v) {
  std::ofstream out(p);
  out << v;
  out.flush();
  ASSERT_TRUE(out.good()) << "cannot write " << p;
}

// ---------------------------------------------------------------- CAN on vcan0
struct VcanRig {
  VcanRig(const fw::Cia402Config& cfg)
      : twin_port(fw::CanPort::open_raw("vcan0", twin_filters())),
        twin(twin_port.fd(), clock),
        galvo(fw::CanGalvo::open("vcan0", cfg)) {}
  static std::vector<can_filter> twin_filters() {
    constexpr canid_t m = CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG;
    return {{0x000, m}, {0x601, m}, {0x201, m}};
  }
  fw::GalvoStatus tick() {
    next += kMs;
    clock.sleep_until(next);
    twin.poll();
    return status = galvo->poll(clock.now());
  }
  bool run_until(const std::function<bool(const fw::GalvoStatus&)>& pred, Nanos budget) {
    next = clock.now();
    const Nanos end = next + budget;
    while (clock.now() < end)
      if (pred(tick())) return true;
    return false;
  }
  MonotonicClock clock;
  fw::CanPort twin_port;
  sim::Cia402Twin twin;
  std::unique_ptr<fw::CanGalvo> galvo;
  fw::GalvoStatus status;
  Nanos next = 0;
};

TEST(VmCan, MasterDrivesTheTwinOverVcan0) {
  REQUIRE_VM();
  fw::Cia402Config cfg;
  cfg.heartbeat_ms = 100;
  cfg.sdo_timeout = 100 * kMs;  // TCG is slow
  cfg.state_timeout = 2000 * kMs;
  VcanRig rig(cfg);
  const Nanos t0 = rig.clock.now();
  rig.galvo->enable(t0);
  ASSERT_TRUE(rig.run_until(
      [](const fw::GalvoStatus& s) { return s.enabled || s.fault != fw::GalvoFault::None; }, 5000 * kMs));
  ASSERT_TRUE(rig.status.enabled) << fw::to_string(rig.status.fault);
  std::printf("VMRESULT can_enable_ms %.1f\n", double(rig.clock.now() - t0) / 1e6);
  EXPECT_EQ(rig.twin.state(), cia402::DriveState::OperationEnabled);
  const Nanos t1 = rig.clock.now();
  rig.galvo->move_to(4000, t1);
  ASSERT_TRUE(rig.run_until([](const fw::GalvoStatus& s) { return s.in_position; }, 5000 * kMs));
  std::printf("VMRESULT can_move_4000_steps_ms %.1f (profile: 250 ms)\n", double(rig.clock.now() - t1) / 1e6);
  EXPECT_EQ(rig.twin.position(), 4000.0);
  EXPECT_EQ(rig.status.measured_step, 4000.0);
  // receive timestamps from SO_TIMESTAMPING, moved onto CLOCK_MONOTONIC
  const Nanos kts = rig.galvo->master().diagnostics().last_rx_kernel_ts;
  EXPECT_NE(kts, 0);
  EXPECT_LT(std::llabs(rig.clock.now() - kts), 1000 * kMs);
  EXPECT_EQ(rig.galvo->port().tx_errors(), 0u);
}

TEST(VmCan, HeartbeatLossOnVcan0IsDetectedWithinThreeProducerPeriods) {
  REQUIRE_VM();
  fw::Cia402Config cfg;
  cfg.heartbeat_ms = 100;
  cfg.sdo_timeout = 100 * kMs;
  cfg.state_timeout = 2000 * kMs;
  VcanRig rig(cfg);
  rig.galvo->enable(rig.clock.now());
  ASSERT_TRUE(rig.run_until([](const fw::GalvoStatus& s) { return s.enabled; }, 5000 * kMs));
  ASSERT_FALSE(
      rig.run_until([](const fw::GalvoStatus& s) { return s.fault != fw::GalvoFault::None; }, 500 * kMs));
  rig.twin.set_heartbeat_loss(true);
  const Nanos last = rig.twin.last_heartbeat_sent();
  ASSERT_TRUE(
      rig.run_until([](const fw::GalvoStatus& s) { return s.fault != fw::GalvoFault::None; }, 2000 * kMs));
  EXPECT_EQ(rig.status.fault, fw::GalvoFault::CommLost);
  const double ms = double(rig.clock.now() - last) / 1e6;
  std::printf("VMRESULT can_heartbeat_loss_detect_ms %.1f (producer 100 ms)\n", ms);
  // Detected after the consumer timeout, not at the next state poll; generous upper bound: the VM runs under
  // TCG on a shared host, where scheduling spikes of hundreds of ms happen (the value is printed above).
  EXPECT_LT(ms, 1500.0);
  rig.twin.set_heartbeat_loss(false);
  rig.galvo->reset_fault(rig.clock.now());
  ASSERT_TRUE(rig.run_until([](const fw::GalvoStatus& s) { return s.enabled; }, 5000 * kMs));
}

TEST(VmCan, ErrorFramesOnVcan0ReachTheMasterThroughItsErrorFilter) {
  REQUIRE_VM();
  fw::Cia402Config cfg;
  cfg.sdo_timeout = 100 * kMs;
  cfg.state_timeout = 2000 * kMs;
  VcanRig rig(cfg);
  rig.galvo->enable(rig.clock.now());
  ASSERT_TRUE(rig.run_until([](const fw::GalvoStatus& s) { return s.enabled; }, 5000 * kMs));
  rig.twin.inject_bus_off(300 * kMs);  // an error frame written on vcan0, then silence, then "restarted"
  ASSERT_TRUE(
      rig.run_until([](const fw::GalvoStatus& s) { return s.fault != fw::GalvoFault::None; }, 1000 * kMs));
  EXPECT_EQ(rig.status.fault, fw::GalvoFault::BusOff);
  rig.galvo->reset_fault(rig.clock.now());
  ASSERT_TRUE(rig.run_until([](const fw::GalvoStatus& s) { return s.enabled; }, 5000 * kMs));
  EXPECT_FALSE(rig.galvo->master().diagnostics().bus_off);
}

// ---------------------------------------------------------------- GPIO on gpio-sim
struct SimChip {
  std::string label = "facetscan-sim";
  stdfs::path sysfs;  // /sys/devices/platform/gpio-sim.N/gpiochipM
  SimChip() {
    const stdfs::path cfg = "/sys/kernel/config/gpio-sim/facetscan";
    sysfs = stdfs::path("/sys/devices/platform") / slurp(cfg / "dev_name") / slurp(cfg / "bank0/chip_name");
  }
  stdfs::path line(int i) const { return sysfs / ("sim_gpio" + std::to_string(i)); }
  int value(int i) const { return std::stoi(slurp(line(i) / "value")); }
};

// Forwards to the real lines and reads every step edge back from gpio-sim's sysfs value.
class SysfsCountingLines final : public fw::GpioLines {
 public:
  SysfsCountingLines(fw::GpioLines& l, const SimChip& c) : l_(l), chip_(c) {}
  void set_step(bool level, Nanos now) override {
    l_.set_step(level, now);
    const int v = chip_.value(0);
    if (v == 1 && last_ == 0) ++rising_;
    if (v != int(level)) ++mismatch_;
    last_ = v;
  }
  void set_dir(bool level, Nanos now) override { l_.set_dir(level, now); }
  void set_enable(bool level, Nanos now) override { l_.set_enable(level, now); }
  bool read_home(Nanos now) override { return l_.read_home(now); }
  bool next_home_edge(fw::GpioEdge& e) override { return l_.next_home_edge(e); }
  void safe() noexcept override { l_.safe(); }
  int rising_ = 0, mismatch_ = 0, last_ = 0;

 private:
  fw::GpioLines& l_;
  const SimChip& chip_;
};

TEST(VmGpio, StepPulsesAreSeenOnGpioSimAndHomeEdgesAreTimestamped) {
  REQUIRE_VM();
  SimChip chip;
  ASSERT_TRUE(stdfs::exists(chip.sysfs)) << chip.sysfs;
  auto b = fw::make_gpio_backend("gpio:" + chip.label + ":step=0,dir=1,en=2,home=3,laser=4,en_active_low=1");
  ASSERT_TRUE(b.laser);
  auto& lines = static_cast<fw::GpiodLines&>(*b.lines);
  std::printf("VMRESULT gpio %s\n", lines.describe().c_str());
  EXPECT_EQ(chip.value(2), 1);  // enable line active low: off = high
  EXPECT_EQ(chip.value(4), 0);  // laser off
  MonotonicClock clock;
  // direct pulses, each edge read back through sysfs
  SysfsCountingLines counted(*b.lines, chip);
  for (int i = 0; i < 200; ++i) {
    counted.set_step(true, clock.now());
    counted.set_step(false, clock.now());
  }
  EXPECT_EQ(counted.rising_, 200);
  EXPECT_EQ(counted.mismatch_, 0);
  EXPECT_EQ(lines.step_pulses(), 200u);
  // the stepper galvo (firmware) on the real lines: a 60-step move, counted on the chip
  counted.rising_ = 0;
  {
    fw::StepperGalvoParams p;
    p.max_step_rate = 2000;
    fw::StepperGalvo galvo(counted, p);
    galvo.enable(clock.now());
    EXPECT_EQ(chip.value(2), 0);  // enabled: active low
    galvo.move_to(60, clock.now());
    fw::GalvoStatus s;
    const Nanos end = clock.now() + 5000 * kMs;
    while (clock.now() < end) {
      s = galvo.poll(clock.now());
      if (s.in_position) break;
      clock.sleep_until(clock.now() + 100'000);
    }
    EXPECT_TRUE(s.in_position);
    EXPECT_EQ(counted.rising_, 60);
    galvo.move_to(20, clock.now());
    while (!(s = galvo.poll(clock.now())).in_position) clock.sleep_until(clock.now() + 100'000);
    EXPECT_EQ(counted.rising_, 100);
    galvo.disable();
  }
  // home switch: pull changes on the simulated line -> edge events with CLOCK_MONOTONIC timestamps
  fw::GpioEdge e;
  while (b.lines->next_home_edge(e)) {
  }
  const Nanos before = fw::monotonic_now();
  put(chip.line(3) / "pull", "pull-up");
  const Nanos after = fw::monotonic_now();
  bool got = false;
  for (int i = 0; i < 200 && !(got = b.lines->next_home_edge(e)); ++i) clock.sleep_until(clock.now() + kMs);
  ASSERT_TRUE(got);
  EXPECT_TRUE(e.rising);
  EXPECT_GE(e.timestamp, before);
  EXPECT_LE(e.timestamp, after + 1000 * kMs);  // kernel timestamp of the edge; generous for a loaded TCG VM
  EXPECT_TRUE(b.lines->read_home(clock.now()));
  put(chip.line(3) / "pull", "pull-down");
  got = false;
  for (int i = 0; i < 200 && !(got = b.lines->next_home_edge(e)); ++i) clock.sleep_until(clock.now() + kMs);
  ASSERT_TRUE(got);
  EXPECT_FALSE(e.rising);
  EXPECT_FALSE(b.lines->read_home(clock.now()));
  // laser, then the safe state
  b.laser->set(true, clock.now());
  b.lines->set_enable(true, clock.now());
  EXPECT_EQ(chip.value(4), 1);
  EXPECT_EQ(chip.value(2), 0);
  b.lines->safe();
  EXPECT_EQ(chip.value(4), 0);
  EXPECT_EQ(chip.value(2), 1);
  EXPECT_EQ(chip.value(0), 0);
  // requested once: a second request of the same lines is refused with a clear error
  try {
    fw::make_gpio_backend("gpio:" + chip.label + ":step=0,dir=1,en=2,home=3");
    ADD_FAILURE() << "second request succeeded";
  } catch (const fs::Error& err) {
    EXPECT_NE(std::string(err.what()).find("cannot request"), std::string::npos) << err.what();
  }
}

TEST(VmGpio, LinesByNameAndChipByPath) {
  REQUIRE_VM();
  SimChip chip;
  const std::string dev = "/dev/" + chip.sysfs.filename().string();
  auto b = fw::make_gpio_backend("gpio:" + dev + ":step=STEP,dir=DIR,en=EN,home=HOME,laser=LASER");
  MonotonicClock clock;
  b.lines->set_dir(true, clock.now());
  EXPECT_EQ(chip.value(1), 1);
  b.laser->set(true, clock.now());
  EXPECT_EQ(chip.value(4), 1);
  b.laser->force_off();
  EXPECT_EQ(chip.value(4), 0);
  EXPECT_THROW(fw::make_gpio_backend("gpio:" + dev + ":step=NOPE,dir=DIR,en=EN,home=HOME"), fs::Error);
  // a laser on its own line (the CAN galvo's scanner), active low
  {
    auto laser = fw::make_gpio_laser("gpio:" + chip.label + ":line=5,active_low=1");
    EXPECT_EQ(chip.value(5), 1);  // off
    laser->set(true, clock.now());
    EXPECT_TRUE(laser->is_on());
    EXPECT_EQ(chip.value(5), 0);
    laser->force_off();
    EXPECT_FALSE(laser->is_on());
    EXPECT_EQ(chip.value(5), 1);
  }
}

// ---------------------------------------------------------------- V4L2
constexpr std::uint32_t kW = 640, kH = 480;

double truth_col(std::uint32_t k, std::uint32_t y) {
  return 40.0 + 13.37 * k + 0.25 * y + 0.1 * std::sin(0.05 * y);
}

// Gaussian stripe (sigma 1.6 px, amplitude 170 over 12) whose centre follows truth_col; frame number in row
// 0.
void render(std::vector<std::uint8_t>& img, std::uint32_t k, bool yuyv) {
  const std::uint32_t bpp = yuyv ? 2 : 1;
  img.assign(std::size_t(kW) * kH * bpp, 0);
  for (std::uint32_t y = 0; y < kH; ++y) {
    const double c = truth_col(k, y);
    for (std::uint32_t x = 0; x < kW; ++x) {
      const double d = (double(x) - c) / 1.6;
      double v = 12.0 + 170.0 * std::exp(-0.5 * d * d);
      if (y == 0) v = x < 8 ? double((k >> x) & 1) * 255.0 : 0.0;  // frame number, bit by bit
      img[(std::size_t(y) * kW + x) * bpp] = static_cast<std::uint8_t>(std::lround(v));
      if (yuyv) img[(std::size_t(y) * kW + x) * 2 + 1] = 128;  // chroma
    }
  }
}

std::uint32_t frame_number(const fw::FrameView& f, std::uint32_t bpp) {
  std::uint32_t k = 0;
  for (int b = 0; b < 8; ++b)
    if (f.data[b * bpp] > 127) k |= 1u << b;
  return k;
}

void loopback_capture(std::uint32_t fourcc, const char* fmt_name) {
  const bool yuyv = fourcc == V4L2_PIX_FMT_YUYV;
  const std::uint32_t bpp = yuyv ? 2 : 1;
  std::vector<std::uint8_t> img;
  render(img, 0, yuyv);
  const LoopbackOutput out(kW, kH, fourcc, img);
  ASSERT_GE(out.fd(), 0) << fmt_name << ": " << out.error();

  fw::V4l2Camera cam(
      fw::parse_v4l2_spec(std::string("v4l2:/dev/video10:fmt=") + fmt_name + ",width=640,height=480"));
  EXPECT_EQ(cam.width(), kW);
  EXPECT_GE(cam.buffer_count(), 4u);
  std::printf("VMRESULT v4l2loopback %s driver=%s buffers=%u notes='%s'\n", fmt_name, cam.driver().c_str(),
              cam.buffer_count(), cam.notes().c_str());
  cam.start(fw::monotonic_now());
  std::atomic<bool> stop{false};
  constexpr std::uint32_t kFrames = 30;
  std::thread writer([&] {
    std::vector<std::uint8_t> im;
    for (std::uint32_t k = 1; k <= kFrames && !stop; ++k) {
      render(im, k, yuyv);
      if (::write(out.fd(), im.data(), im.size()) != static_cast<ssize_t>(im.size())) break;
      ::usleep(40'000);
    }
  });
  std::vector<msg::StripePoint> pts(kH);
  fw::ExtractParams ep;
  std::uint32_t got = 0, checked_rows = 0;
  double max_err = 0;
  std::uint32_t last_k = 0;
  Nanos last_ts = 0;
  const Nanos end = fw::monotonic_now() + 20000 * kMs;
  while (last_k < kFrames && fw::monotonic_now() < end) {
    fw::FrameView fv;
    const auto r = cam.grab(fw::monotonic_now() + 2000 * kMs, fv);
    if (r != fw::GrabResult::Ok) continue;
    EXPECT_TRUE(cam.owns_pointer(fv.data));
    const std::uint32_t k = frame_number(fv, bpp);
    if (k > 0 && k != last_k) {
      ++got;
      const auto counts = fw::extract_frame(fv, ep, pts);
      for (std::uint32_t i = 0; i < counts.points; ++i) {
        if (pts[i].row == 0) continue;
        max_err = std::max(max_err, std::abs(double(pts[i].col) - truth_col(k, pts[i].row)));
        ++checked_rows;
      }
      EXPECT_GE(counts.points, kH - 1);
      if (last_ts) {
        EXPECT_GT(fv.timestamp, last_ts);
      }
      last_ts = fv.timestamp;
      last_k = k;
    }
    cam.release(fv);
  }
  stop = true;
  writer.join();
  cam.stop();
  std::printf(
      "VMRESULT v4l2loopback %s frames=%u rows=%u max_centre_error_px=%.4f dropped=%u non_monotonic=%llu\n",
      fmt_name, got, checked_rows, max_err, cam.frames_dropped(),
      static_cast<unsigned long long>(cam.stats().non_monotonic));
  EXPECT_GE(got, kFrames / 2);
  EXPECT_EQ(last_k, kFrames);
  EXPECT_GT(checked_rows, 0u);
  EXPECT_LT(max_err, 0.05);
}

TEST(VmV4l2, LoopbackGreyStripesGiveTheGroundTruthCentres) {
  REQUIRE_VM();
  loopback_capture(V4L2_PIX_FMT_GREY, "GREY");
}

TEST(VmV4l2, LoopbackYuyvLumaStripesGiveTheGroundTruthCentres) {
  REQUIRE_VM();
  loopback_capture(V4L2_PIX_FMT_YUYV, "YUYV");
}

TEST(VmV4l2, VividCaptureStreamsWithMonotonicTimestamps) {
  REQUIRE_VM();
  for (const char* fmt : {"GREY", "Y16"}) {
    fw::V4l2Camera cam(
        fw::parse_v4l2_spec(std::string("v4l2:/dev/video0:fmt=") + fmt + ",width=320,height=240,fps=25"));
    std::printf("VMRESULT vivid %s driver=%s %ux%u stride=%u buffers=%u notes='%s'\n", fmt,
                cam.driver().c_str(), cam.width(), cam.height(), cam.stride(), cam.buffer_count(),
                cam.notes().c_str());
    cam.start(fw::monotonic_now());
    std::uint32_t last_seq = 0;
    Nanos last_ts = 0;
    int frames = 0;
    for (int i = 0; i < 4; ++i) {
      fw::FrameView fv;
      ASSERT_EQ(cam.grab(fw::monotonic_now() + 5000 * kMs, fv), fw::GrabResult::Ok);
      if (i) {
        EXPECT_GE(fv.sequence, last_seq);
        EXPECT_GT(fv.timestamp, last_ts);
      }
      EXPECT_LT(std::llabs(fw::monotonic_now() - fv.timestamp), 5000 * kMs);
      last_seq = fv.sequence;
      last_ts = fv.timestamp;
      ++frames;
      cam.release(fv);
    }
    EXPECT_EQ(cam.stats().non_monotonic, 0u);
    std::printf("VMRESULT vivid %s frames=%d dropped=%u sequence_restarts=%llu\n", fmt, frames,
                cam.frames_dropped(), static_cast<unsigned long long>(cam.stats().sequence_restarts));
    cam.stop();
  }
}

}  // namespace
}  // namespace fs::vmtest
