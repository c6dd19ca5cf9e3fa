// Frames per second of the stripe renderer at 1280x1024 with noise (target >= 100 on one core), and the cost
// of the parts: stripe geometry (ray casting) alone, and a full ground-truth grid.
#include <benchmark/benchmark.h>

#include <vector>

#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/stripe_renderer.hpp"
#include "support/test_paths.hpp"

namespace {

const fs::sim::Scene& scene() {
  static const fs::sim::Scene s = fs::sim::load_scene(fs::test::source_dir() / "hw-sim/scenes/default.json");
  return s;
}

void render(benchmark::State& state, fs::sim::FrameFormat format, bool reflection) {
  const auto& s = scene();
  fs::sim::RenderOptions opt;
  opt.spurious_reflection = reflection;
  fs::sim::StripeRenderer r(s, opt);
  const auto& cam = s.calibration.camera;
  const std::uint32_t bpp = format == fs::sim::FrameFormat::Mono16 ? 2 : 1;
  std::vector<std::uint8_t> pixels(static_cast<std::size_t>(cam.width) * bpp * cam.height + 64);
  fs::sim::FrameBuffer fb{pixels.data(), cam.width, cam.height, cam.width * bpp, format};
  std::uint64_t frame = 0;
  for (auto _ : state) {
    // Sweep across the scene so frames hit objects, table and shadows.
    r.render_step(static_cast<double>(frame % s.calibration.step_count), frame, fb);
    benchmark::DoNotOptimize(pixels.data());
    ++frame;
  }
  state.counters["frames/s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

void BM_RenderMono8Noise(benchmark::State& state) { render(state, fs::sim::FrameFormat::Mono8, false); }
void BM_RenderMono16Noise(benchmark::State& state) { render(state, fs::sim::FrameFormat::Mono16, false); }
void BM_RenderMono8NoiseReflection(benchmark::State& state) {
  render(state, fs::sim::FrameFormat::Mono8, true);
}

void BM_StripeGeometryOnly(benchmark::State& state) {
  const auto& s = scene();
  fs::sim::StripeTracer t(s);
  std::vector<fs::sim::StripeSample> rows(s.calibration.camera.height);
  std::uint64_t k = 0;
  for (auto _ : state) {
    t.trace(s.calibration.laser.plane_at_step(static_cast<double>(k++ % s.calibration.step_count)), rows);
    benchmark::DoNotOptimize(rows.data());
  }
  state.counters["planes/s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

void BM_GroundTruthGrid500Steps(benchmark::State& state) {
  for (auto _ : state) {
    auto g = fs::sim::make_ground_truth_grid(scene());
    benchmark::DoNotOptimize(g.cells().data());
  }
}

BENCHMARK(BM_RenderMono8Noise)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RenderMono16Noise)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RenderMono8NoiseReflection)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_StripeGeometryOnly)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GroundTruthGrid500Steps)->Unit(benchmark::kMillisecond)->Iterations(2);

}  // namespace

BENCHMARK_MAIN();
