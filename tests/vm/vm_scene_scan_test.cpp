// Runs INSIDE the test VM: a small scan of the hw-sim demo scene through the real backends and real drivers.
// "Hardware" threads: the CiA 402 drive twin on vcan0 (1 kHz) and a camera thread that renders the scene
// (hw-sim StripeRenderer, noise-free) for the twin's current position and writes the frames into
// v4l2loopback. "Firmware" (this thread): CanGalvo on vcan0 moves to each step, V4l2Camera captures from the
// loopback, the firmware's stripe extractor finds the centres; the captured frame must equal the render of
// that step byte for byte and the extracted centres must match the renderer's ground truth.
#include <gtest/gtest.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <thread>
#include <vector>

#include "common/messages.hpp"
#include "firmware/backends/gpiod_lines.hpp"
#include "firmware/backends/v4l2_camera.hpp"
#include "firmware/extract/stripe_extractor.hpp"
#include "firmware/galvo/can_galvo.hpp"
#include "firmware/loop/monotonic_clock.hpp"
#include "hw-sim/scene/scene.hpp"
#include "hw-sim/scene/stripe_renderer.hpp"
#include "support/test_paths.hpp"
#include "vm_rig.hpp"

namespace fs::vmtest {
namespace {

using fw::Nanos;
constexpr Nanos kMs = 1'000'000;

using fw::MonotonicClock;

TEST(VmScan, DemoSceneThroughCanGalvoAndV4l2Loopback) {
  if (!std::getenv("FACETSCAN_VM")) GTEST_SKIP() << "runs only inside the test VM (tests/vm/run_vm.sh)";
  const sim::Scene scene = sim::load_scene(test::source_dir() / "hw-sim/scenes/default.json");
  const std::uint32_t W = scene.calibration.camera.width, H = scene.calibration.camera.height;
  sim::RenderOptions ro;
  ro.noise_scale = 0.0;

  // --- the scanner hardware ---
  MonotonicClock clock;
  const VcanDriveTwin twin(clock, scene.calibration.first_step);
  const LoopbackOutput out(W, H);
  ASSERT_GE(out.fd(), 0) << out.error();
  std::atomic<std::int64_t> written_pos{-1};  // position of the last frame written
  std::atomic<int> written_count{0};
  const std::jthread camera([&](std::stop_token stop) {  // stopped and joined before `out` and `twin` go
    sim::StripeRenderer r(scene, ro);
    std::vector<std::uint8_t> img(W * H);
    const sim::FrameBuffer fb{img.data(), W, H, W, sim::FrameFormat::Mono8};
    while (!stop.stop_requested()) {
      const double p = twin.position();
      r.render_step(p, 1, fb);
      if (::write(out.fd(), img.data(), img.size()) != static_cast<ssize_t>(img.size())) break;
      written_pos = std::llround(p);
      ++written_count;
      ::usleep(5000);
    }
  });

  // --- the firmware side ---
  fw::Cia402Config cfg;
  cfg.heartbeat_ms =
      1000;  // rendering + extraction on TCG's one vCPU can starve the twin's thread for >200 ms
  cfg.sdo_timeout = 100 * kMs;
  cfg.state_timeout = 2000 * kMs;
  auto galvo = fw::CanGalvo::open("vcan0", cfg);
  fw::V4l2Spec vs;
  vs.device = "/dev/video10";
  vs.width = W;
  vs.height = H;
  fw::V4l2Camera cam(vs);
  cam.start(clock.now());
  auto poll_until = [&](const std::function<bool(const fw::GalvoStatus&)>& pred, Nanos budget) {
    const Nanos end = clock.now() + budget;
    fw::GalvoStatus s;
    while (clock.now() < end) {
      s = galvo->poll(clock.now());
      if (pred(s)) return true;
      clock.sleep_until(clock.now() + kMs);
    }
    return false;
  };
  galvo->enable(clock.now());
  ASSERT_TRUE(poll_until([](const fw::GalvoStatus& s) { return s.enabled; }, 5000 * kMs));

  sim::StripeRenderer truth_r(scene, ro);
  std::vector<std::uint8_t> expect(W * H);
  const sim::FrameBuffer efb{expect.data(), W, H, W, sim::FrameFormat::Mono8};
  std::vector<msg::StripePoint> pts(H);
  fw::ExtractParams ep;
  std::vector<double> errors;
  int steps_done = 0, exact = 0;
  const std::int32_t s0 = scene.calibration.first_step;
  const auto n = static_cast<std::int32_t>(scene.calibration.step_count);
  const Nanos t_scan = clock.now();
  for (std::int32_t k : {s0 + n / 4, s0 + n / 2 - 7, s0 + n / 2 + 20, s0 + 3 * n / 4}) {
    galvo->move_to(k, clock.now());
    ASSERT_TRUE(poll_until([](const fw::GalvoStatus& s) { return s.in_position; }, 5000 * kMs))
        << "step " << k;
    // wait for two frames rendered at k, then take the newest frame the driver has
    const int c0 = written_count;
    ASSERT_TRUE(poll_until(
        [&](const fw::GalvoStatus&) { return written_pos == k && written_count >= c0 + 2; }, 20000 * kMs));
    fw::FrameView fv{}, last{};
    bool have = false;
    while (cam.grab(clock.now() + (have ? 50 : 3000) * kMs, fv) == fw::GrabResult::Ok) {
      if (have) cam.release(last);
      last = fv;
      have = true;
      (void)galvo->poll(clock.now());
    }
    ASSERT_TRUE(have);
    truth_r.render_step(k, 1, efb);
    const bool same = std::equal(expect.begin(), expect.end(), last.data);
    exact += same;
    const auto counts = fw::extract_frame(last, ep, pts);
    const auto truth = truth_r.truth();
    for (std::uint32_t i = 0; i < counts.points; ++i) {
      const auto& t = truth[pts[i].row];
      if (t.object < 0 || std::isnan(t.column)) continue;  // rows with no lit, seen point
      errors.push_back(std::abs(double(pts[i].col) - t.column));
    }
    std::printf("VMRESULT scan step %d: points=%u exact_frame=%d\n", k, counts.points, int(same));
    EXPECT_GT(counts.points, H / 4);
    cam.release(last);
    ++steps_done;
  }
  const double scan_s = double(clock.now() - t_scan) / 1e9;
  cam.stop();
  galvo->disable();
  std::sort(errors.begin(), errors.end());
  const double median = errors.empty() ? 1e9 : errors[errors.size() / 2];
  const double p95 = errors.empty() ? 1e9 : errors[errors.size() * 95 / 100];
  std::printf(
      "VMRESULT scan steps=%d exact_frames=%d object_rows=%zu centre_error_px median=%.4f p95=%.4f "
      "time_s=%.1f\n",
      steps_done, exact, errors.size(), median, p95, scan_s);
  EXPECT_EQ(steps_done, 4);
  EXPECT_EQ(exact, 4);
  EXPECT_FALSE(errors.empty());
  EXPECT_LT(median, 0.1);
}

}  // namespace
}  // namespace fs::vmtest
