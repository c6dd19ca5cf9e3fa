// Runs INSIDE the test VM: the whole firmware (the facetscan-fw binary, its controller loop) scans a scene
// with
// --galvo can:vcan0 --camera v4l2:/dev/video10 --laser gpio:facetscan-sim:line=5, i.e. through the real
// SocketCAN, V4L2 (v4l2loopback) and GPIO (gpio-sim) drivers.
// "Hardware" (threads of this test): the CiA 402 drive twin on vcan0, and a camera that renders the demo
// scene (hw-sim StripeRenderer, noise-free, 640x512) for the twin's position — with the stripe only while the
// laser line on gpio-sim reads 1 (sysfs), and only frames whose laser state and position did not change
// during the render are written — into v4l2loopback. Before the scan, `facetscan-fw --check` must find every
// device. The recorded .fscan must hold one stripe per step whose centres match the renderer's ground truth
// there.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "common/scan_file.hpp"
#include "firmware/loop/monotonic_clock.hpp"
#include "hw-sim/scene/scene.hpp"
#include "hw-sim/scene/stripe_renderer.hpp"
#include "support/test_paths.hpp"
#include "vm_rig.hpp"

extern char** environ;

namespace fs::vmtest {
namespace {

namespace stdfs = std::filesystem;
using fw::Nanos;

std::string slurp_trim(const stdfs::path& p) {
  std::ifstream f(p);
  std::string s((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s;
}

// Runs argv, stdout+stderr to `log`; kills it after `timeout_s`. Returns the exit status (-1 killed /
// failed).
int run(const std::vector<std::string>& args, const std::string& log, int timeout_s) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, argv[0], &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) return -1;
  for (int i = 0; i < timeout_s * 20; ++i) {
    int st = 0;
    if (::waitpid(pid, &st, WNOHANG) == pid) return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    ::usleep(50000);
  }
  ::kill(pid, SIGKILL);
  ::waitpid(pid, nullptr, 0);
  return -1;
}

TEST(VmLoopScan, FirmwareBinaryScansThroughCanV4l2AndGpioSim) {
  if (!std::getenv("FACETSCAN_VM")) GTEST_SKIP() << "runs only inside the test VM (tests/vm/run_vm.sh)";
  sim::Scene scene = sim::load_scene(test::source_dir() / "hw-sim/scenes/default.json");
  {  // half resolution: 4x less rendering under TCG
    auto& c = scene.calibration.camera;
    c.width /= 2;
    c.height /= 2;
    c.fx /= 2;
    c.fy /= 2;
    c.cx = (c.cx + 0.5) / 2 - 0.5;
    c.cy = (c.cy + 0.5) / 2 - 0.5;
  }
  const std::uint32_t W = scene.calibration.camera.width, H = scene.calibration.camera.height;
  sim::RenderOptions ro;
  ro.noise_scale = 0.0;
  constexpr int kLaserLine = 5;
  constexpr std::uint32_t kSteps = 5;
  const std::int32_t first =
      scene.calibration.first_step + static_cast<std::int32_t>(scene.calibration.step_count) / 2 - 2;

  const stdfs::path gcfg = "/sys/kernel/config/gpio-sim/facetscan";
  const stdfs::path laser_value = stdfs::path("/sys/devices/platform") / slurp_trim(gcfg / "dev_name") /
                                  slurp_trim(gcfg / "bank0/chip_name") /
                                  ("sim_gpio" + std::to_string(kLaserLine)) / "value";
  ASSERT_TRUE(stdfs::exists(laser_value)) << laser_value;
  auto laser_on = [&] { return slurp_trim(laser_value) == "1"; };

  // --- the scanner hardware ---
  fw::MonotonicClock clock;
  const VcanDriveTwin twin(clock, first - 30);
  const LoopbackOutput out(W, H);
  ASSERT_GE(out.fd(), 0) << out.error();
  std::atomic<int> written{0}, discarded{0};
  const std::jthread camera([&](std::stop_token stop) {  // stopped and joined before `out` and `twin` go
    sim::StripeRenderer r(scene, ro);
    std::vector<std::uint8_t> img(std::size_t(W) * H);
    const sim::FrameBuffer fb{img.data(), W, H, W, sim::FrameFormat::Mono8};
    while (!stop.stop_requested()) {
      if (!laser_on()) {
        ::usleep(500);
        continue;
      }
      const double p = twin.position();
      r.render_step(p, 1, fb);
      if (!laser_on() || twin.position() != p) {
        ++discarded;
        continue;
      }
      if (::write(out.fd(), img.data(), img.size()) != static_cast<ssize_t>(img.size())) break;
      ++written;
    }
  });

  // --- the firmware: the facetscan-fw binary ---
  const std::string fw_bin = FACETSCAN_FW_BIN;
  // Heartbeat 1 s (tolerance 2 s): on one emulated vCPU the frame extraction takes ~100 ms of CPU per frame
  // and the drive twin's thread can be starved for 250 ms, past the default 100 ms producer time's 200 ms
  // limit.
  const std::string galvo = "can:vcan0:node=1,hb=1000,sdo_ms=200,state_ms=5000";
  const std::string cam =
      "v4l2:/dev/video10:fmt=GREY,width=" + std::to_string(W) + ",height=" + std::to_string(H);
  const std::string laser = "gpio:facetscan-sim:line=" + std::to_string(kLaserLine);
  const int check_rc =
      run({fw_bin, "--check", "--galvo", galvo, "--camera", cam, "--laser", laser}, "/tmp/fw_check.log", 60);
  std::printf("VMRESULT fw --check rc=%d\n%s", check_rc, slurp_trim("/tmp/fw_check.log").c_str());
  std::printf("\n");
  EXPECT_EQ(check_rc, 0);
  // and a missing device is reported
  const int miss_rc = run({fw_bin, "--check", "--galvo", "can:vcan9", "--camera", "v4l2:/dev/video99",
                           "--laser", "gpio:facetscan-sim:line=99"},
                          "/tmp/fw_check_miss.log", 60);
  const std::string miss = slurp_trim("/tmp/fw_check_miss.log");
  std::printf("VMRESULT fw --check (missing devices) rc=%d\n%s\n", miss_rc, miss.c_str());
  EXPECT_EQ(miss_rc, 3);
  EXPECT_NE(miss.find("no network interface 'vcan9'"), std::string::npos);
  EXPECT_NE(miss.find("cannot open /dev/video99"), std::string::npos);
  EXPECT_NE(miss.find("offset 99 out of range"), std::string::npos);

  {
    std::ofstream cfgf("/tmp/fw_vm.json");
    cfgf << R"({"first_step": )" << first << R"(, "steps": )" << kSteps
         << R"(, "loop": {"period_us": 2000, "max_dwell_ms": 30000, "camera_timeout_ms": 30000,
              "late_limit_us": 1000000, "max_consecutive_late": 1000, "homing_timeout_ms": 30000,
              "move_timeout_ms": 30000, "heartbeat_ms": 500}})";
  }
  const Nanos t0 = clock.now();
  const int rc = run({fw_bin, "--config", "/tmp/fw_vm.json", "--galvo", galvo, "--camera", cam, "--laser",
                      laser, "--record", "/tmp/vm_loop.fscan"},
                     "/tmp/fw_scan.log", 240);
  const double scan_s = double(clock.now() - t0) / 1e9;
  std::printf("VMRESULT fw scan rc=%d time_s=%.1f frames_written=%d discarded=%d\n%s\n", rc, scan_s,
              written.load(), discarded.load(), slurp_trim("/tmp/fw_scan.log").c_str());
  ASSERT_EQ(rc, 0);
  EXPECT_FALSE(laser_on()) << "the laser line must be off after the scan";

  // --- the recording: one stripe per step, centres on the ground truth of that step ---
  ScanFileReader rd(stdfs::path("/tmp/vm_loop.fscan"));
  wire::DecodedMessage msg;
  sim::StripeRenderer truth_r(scene, ro);
  std::vector<std::uint8_t> img(std::size_t(W) * H);
  const sim::FrameBuffer fb{img.data(), W, H, W, sim::FrameFormat::Mono8};
  std::vector<std::uint32_t> steps;
  std::vector<double> errors;
  std::size_t object_rows = 0, missed = 0;
  bool ended = false;
  while (rd.next(msg)) {
    if (msg.type == msg::Type::ScanEnd) {
      ended = true;
      EXPECT_EQ(msg.scan_end.completed, 1);
      EXPECT_EQ(msg.scan_end.stripes_sent, kSteps);
    }
    if (msg.type != msg::Type::Stripe) continue;
    const auto& h = msg.stripe.header;
    steps.push_back(h.step_index);
    truth_r.render_step(first + static_cast<double>(h.step_index), 1, fb);
    const auto truth = truth_r.truth();
    std::vector<int> got(H, -1);
    for (std::size_t i = 0; i < msg.stripe.points.size(); ++i)
      got[msg.stripe.points[i].row] = static_cast<int>(i);
    std::size_t rows = 0;
    for (std::uint32_t y = 0; y < H; ++y) {
      const auto& t = truth[y];
      if (t.object < 0 || std::isnan(t.column)) continue;
      ++rows;
      if (got[y] < 0) {
        ++missed;
        continue;
      }
      errors.push_back(std::abs(double(msg.stripe.points[got[y]].col) - t.column));
    }
    object_rows += rows;
    std::printf("VMRESULT loop stripe step %u: points=%zu object_rows=%zu measured_position=%.2f\n",
                h.step_index, msg.stripe.points.size(), rows, h.measured_position);
    EXPECT_GT(rows, H / 8) << "step " << h.step_index;
  }
  EXPECT_TRUE(ended);
  ASSERT_EQ(steps.size(), kSteps);
  for (std::uint32_t k = 0; k < kSteps; ++k) EXPECT_EQ(steps[k], k);
  std::sort(errors.begin(), errors.end());
  const double median = errors.empty() ? 1e9 : errors[errors.size() / 2];
  const double p95 = errors.empty() ? 1e9 : errors[errors.size() * 95 / 100];
  std::printf(
      "VMRESULT loop scan steps=%zu object_rows=%zu missed=%zu centre_error_px median=%.4f p95=%.4f "
      "time_s=%.1f\n",
      steps.size(), object_rows, missed, median, p95, scan_s);
  EXPECT_LE(missed, object_rows / 50);
  EXPECT_LT(median, 0.1);
  EXPECT_LT(p95, 0.5);
}

}  // namespace
}  // namespace fs::vmtest
