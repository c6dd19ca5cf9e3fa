// bench_extract: stripe extraction throughput on a 1280x1024 Mono8 frame of the cube scene (scene renderer,
// default noise) next to memcpy of the same frame in the same run. bytes_per_second = pixels per second.
#include <benchmark/benchmark.h>

#include <cstring>
#include <vector>

#include "firmware/extract/stripe_extractor.hpp"
#include "hw-sim/scene/scene.hpp"
#include "hw-sim/scene/stripe_renderer.hpp"
#include "support/test_paths.hpp"

namespace {

struct Frame {
  Frame() : scene(fs::sim::load_scene(fs::test::source_dir() / "hw-sim/scenes/cube.json")) {
    const auto& cam = scene.calibration.camera;
    pixels.resize(static_cast<std::size_t>(cam.width) * cam.height);
    fs::sim::StripeRenderer r(scene);
    r.render_step(250.0, 1, fs::sim::FrameBuffer{pixels.data(), cam.width, cam.height, cam.width,
                                                 fs::sim::FrameFormat::Mono8});
    view = fs::fw::FrameView{pixels.data(), cam.width, cam.height, cam.width, fs::fw::PixelFormat::Mono8, 0, 0, 0};
  }
  fs::sim::Scene scene;
  std::vector<std::uint8_t> pixels;
  fs::fw::FrameView view;
};

Frame& frame() {
  static Frame f;
  return f;
}

void BM_Memcpy(benchmark::State& state) {
  Frame& f = frame();
  std::vector<std::uint8_t> dst(f.pixels.size());
  for (auto _ : state) {
    std::memcpy(dst.data(), f.pixels.data(), f.pixels.size());
    benchmark::DoNotOptimize(dst.data());
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * f.pixels.size()));
}
BENCHMARK(BM_Memcpy);

void BM_Extract(benchmark::State& state) {
  Frame& f = frame();
  fs::fw::ExtractParams p;
  p.method = static_cast<fs::fw::SubpixelMethod>(state.range(0));
  std::vector<fs::msg::StripePoint> out(f.view.height);
  std::uint32_t points = 0;
  for (auto _ : state) {
    const auto c = fs::fw::extract_frame(f.view, p, out);
    points = c.points;
    benchmark::DoNotOptimize(out.data());
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * f.pixels.size()));
  state.SetLabel(std::string(fs::fw::to_string(p.method)) + ", " + std::to_string(points) + " points/frame");
}
BENCHMARK(BM_Extract)->Arg(0)->Arg(1)->Arg(2)->Arg(3);

}  // namespace

BENCHMARK_MAIN();
