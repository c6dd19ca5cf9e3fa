// Benchmarks of the backends' per-cycle costs (release build): one 1 ms loop cycle of the CiA 402 master and
// drive twin over a socketpair (frames through the kernel), and one V4L2 grab + release (fake driver).
#include <benchmark/benchmark.h>

#include "can_rig.hpp"
#include "fake_v4l2.hpp"
#include "firmware/backends/v4l2_camera.hpp"

namespace {

void BM_Cia402CycleMoving(benchmark::State& state) {
  fs::test::CanRig rig;
  rig.enable();
  std::int32_t k = 0;
  for (auto _ : state) {
    if (rig.status.in_position) rig.master.move_to((k += 40) % 4000, rig.clock.now());
    benchmark::DoNotOptimize(rig.tick());
  }
  state.counters["frames_per_cycle"] =
      benchmark::Counter(double(rig.master.diagnostics().frames_rx + rig.master.diagnostics().frames_tx) /
                         double(state.iterations()));
}
BENCHMARK(BM_Cia402CycleMoving);

void BM_V4l2GrabRelease(benchmark::State& state) {
  fs::test::ManualClock clock;
  fs::test::FakeV4l2 fake(clock);
  fs::fw::V4l2Spec s;
  s.device = "/dev/fake0";
  s.width = 1280;
  s.height = 1024;
  fs::fw::V4l2Camera cam(s, fake, &clock);
  cam.start(clock.now());
  std::uint32_t seq = 0;
  for (auto _ : state) {
    state.PauseTiming();
    fake.produce(seq++, 1, [](std::uint8_t*, std::uint32_t) {});
    state.ResumeTiming();
    fs::fw::FrameView f;
    cam.grab(clock.now() + 1'000'000, f);
    cam.release(f);
  }
}
BENCHMARK(BM_V4l2GrabRelease);

}  // namespace
BENCHMARK_MAIN();
