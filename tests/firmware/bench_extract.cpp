// bench_extract: stripe extraction throughput on a 1280x1024 Mono8 frame of the cube scene (scene renderer,
// default noise) next to memcpy of the same frame in the same run. bytes_per_second = pixels per second.
// BM_ExtractVsMemcpy (the frame hot in the caches) and BM_StreamVsMemcpy (the frame in memory, as a camera's
// DMA leaves it): the two readings of the extraction speed criterion (docs/performance.md, stripe
// extraction). memcpy and extraction alternate in one loop; the counters give their medians, pixel rates
// (extract_Gpx_s, memcpy_Gpx_s) and ratios (ratio: of the medians; ratio_paired: the median of each
// iteration's own ratio), and the extraction without software prefetch next to it. BM_StreamPrefetch: the
// camera's frame over prefetch distances. BM_Memcpy / BM_Extract*: one hot frame, apart. BM_ScanRow: the
// per-row pass alone over the frame, 0 = the portable auto-vectorized loop, 1 = the path extraction uses
// (SIMD on x86-64; label says which). BM_GaussMlBatch: the batched sub-pixel fit alone.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include "firmware/extract/gauss_ml.hpp"
#include "firmware/extract/row_scan.hpp"
#include "firmware/extract/stripe_extractor.hpp"
#include "hw-sim/scene/scene.hpp"
#include "hw-sim/scene/stripe_renderer.hpp"
#include "support/test_paths.hpp"
#include "support/thread_cpu.hpp"

namespace {

struct Frame {
  Frame() : scene(fs::sim::load_scene(fs::test::source_dir() / "hw-sim/scenes/cube.json")) {
    const auto& cam = scene.calibration.camera;
    pixels.resize(static_cast<std::size_t>(cam.width) * cam.height);
    fs::sim::StripeRenderer r(scene);
    r.render_step(
        250.0, 1,
        fs::sim::FrameBuffer{pixels.data(), cam.width, cam.height, cam.width, fs::sim::FrameFormat::Mono8});
    view = fs::fw::FrameView{
        pixels.data(), cam.width, cam.height, cam.width, fs::fw::PixelFormat::Mono8, 0, 0, 0};
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

// The speed criterion in one number: memcpy of the frame and its extraction alternate in every iteration,
// each timed by the thread's CPU clock, and the counters give their medians and the ratio (memcpy /
// extraction = extraction's throughput as a fraction of memcpy's). Alternating makes both see the same state
// of this shared, noisy host, where separate benchmarks seconds apart do not. Every iteration also extracts
// once without the software prefetch (ExtractParams::prefetch_rows = 0; which of the two extractions goes
// first alternates): its cost or gain under the same load (no_prefetch_us). Argument: the sub-pixel method.
double thread_cpu_us() { return fs::test::thread_cpu_seconds() * 1e6; }
double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}
// Writes the n bytes at p back to memory and drops them from every cache level (x86-64: CLFLUSH; false
// elsewhere: nothing done).
bool flush_from_caches(const std::uint8_t* p, std::size_t n) {
#if defined(__x86_64__)
  for (std::size_t i = 0; i < n; i += 64) _mm_clflush(p + i);
  _mm_mfence();
  return true;
#else
  (void)p;
  (void)n;
  return false;
#endif
}

// The iterations of such a benchmark on the frame f: memcpy of f, then f extracted twice. cold: f is flushed
// from the caches before each of the three (untimed), so that each reads it from memory.
void interleave_vs_memcpy(benchmark::State& state, bool cold,
                          std::uint32_t prefetch_rows = fs::fw::ExtractParams{}.prefetch_rows) {
  Frame& f = frame();
  const std::size_t n = f.pixels.size();
  std::vector<std::uint8_t> dst(n);
  fs::fw::ExtractParams on;
  on.method = static_cast<fs::fw::SubpixelMethod>(state.range(0));
  on.prefetch_rows = prefetch_rows;
  fs::fw::ExtractParams off = on;
  off.prefetch_rows = 0;
  std::vector<fs::msg::StripePoint> out(f.view.height);
  std::vector<double> copy_us, on_us, off_us;
  copy_us.reserve(1 << 16);
  on_us.reserve(1 << 16);
  off_us.reserve(1 << 16);
  const auto make_cold = [&] {
    if (!cold) return;
    state.PauseTiming();
    flush_from_caches(f.pixels.data(), n);
    state.ResumeTiming();
  };
  const auto timed_extract = [&](const fs::fw::ExtractParams& params) {
    make_cold();
    const double t0 = thread_cpu_us();
    fs::fw::extract_frame(f.view, params, out);
    benchmark::DoNotOptimize(out.data());
    return thread_cpu_us() - t0;
  };
  if (cold && !flush_from_caches(f.pixels.data(), n)) {
    state.SkipWithError("no cache flush on this target");
    return;
  }
  bool on_first = true;
  for (auto _ : state) {
    make_cold();
    const double t0 = thread_cpu_us();
    std::memcpy(dst.data(), f.pixels.data(), n);
    benchmark::DoNotOptimize(dst.data());
    benchmark::ClobberMemory();
    const double copy = thread_cpu_us() - t0;
    const double first = timed_extract(on_first ? on : off);
    const double second = timed_extract(on_first ? off : on);
    if (copy_us.size() < copy_us.capacity()) {
      copy_us.push_back(copy);
      on_us.push_back(on_first ? first : second);
      off_us.push_back(on_first ? second : first);
    }
    on_first = !on_first;
  }
  if (copy_us.empty()) return;
  const double mc = median(copy_us), me = median(on_us);
  std::vector<double> paired(copy_us.size());
  for (std::size_t i = 0; i < paired.size(); ++i) paired[i] = copy_us[i] / on_us[i];
  const double pixels = static_cast<double>(f.view.width) * f.view.height;
  state.counters["memcpy_us"] = mc;
  state.counters["extract_us"] = me;
  state.counters["no_prefetch_us"] = median(off_us);
  state.counters["ratio"] = mc / me;
  // The same ratio per iteration (the memcpy and the extraction right after it), its median: what the host's
  // load does to both in the same few hundred microseconds cancels out of it.
  state.counters["ratio_paired"] = median(paired);
  state.counters["extract_Gpx_s"] = pixels / me * 1e-3;  // pixels per microsecond / 1000
  state.counters["memcpy_Gpx_s"] = pixels / mc * 1e-3;
  state.SetLabel(std::string(fs::fw::to_string(on.method)) + ", prefetch_rows " +
                 std::to_string(on.prefetch_rows));
}

// The hot frame: in the caches for the memcpy and both extractions.
void BM_ExtractVsMemcpy(benchmark::State& state) { interleave_vs_memcpy(state, false); }
BENCHMARK(BM_ExtractVsMemcpy)
    ->Arg(static_cast<int>(fs::fw::SubpixelMethod::GaussMl))
    ->Arg(static_cast<int>(fs::fw::SubpixelMethod::GaussLog))
    ->Arg(static_cast<int>(fs::fw::SubpixelMethod::CentreOfGravity));

// A camera's frame: in memory, not in any cache, as a frame a camera's DMA wrote is when the firmware gets
// it, for the memcpy and for each extraction. The copy's destination is one buffer, hot in the caches as a
// reused buffer is (the demanding case for the ratio: a cold destination would add its reads to the memcpy).
void BM_StreamVsMemcpy(benchmark::State& state) { interleave_vs_memcpy(state, true); }
BENCHMARK(BM_StreamVsMemcpy)
    ->Arg(static_cast<int>(fs::fw::SubpixelMethod::GaussMl))
    ->Arg(static_cast<int>(fs::fw::SubpixelMethod::GaussLog));

// The camera's frame with the prefetch distance as the argument (method: the default), for tuning
// ExtractParams::prefetch_rows on a host or board: the counters as above.
void BM_StreamPrefetch(benchmark::State& state) {
  interleave_vs_memcpy(state, true, static_cast<std::uint32_t>(state.range(1)));
}
BENCHMARK(BM_StreamPrefetch)
    ->ArgsProduct({{static_cast<int>(fs::fw::ExtractParams{}.method)}, {8, 16, 32, 64, 128}});

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
void BM_ScanRow(benchmark::State& state) {
  Frame& f = frame();
  auto scan = std::make_unique<fs::fw::detail::RowScan<std::uint8_t>>();
  std::uint64_t check = 0;
  for (auto _ : state) {
    for (std::uint32_t y = 0; y < f.view.height; ++y) {
      const std::uint8_t* row = f.view.data + static_cast<std::size_t>(y) * f.view.stride;
      if (state.range(0) == 0)
        fs::fw::detail::scan_row_portable<std::uint8_t, 1>(row, f.view.width, *scan);
      else
        fs::fw::detail::scan_row<std::uint8_t, 1>(row, f.view.width, *scan);
      check += scan->sum + scan->max;
    }
    benchmark::DoNotOptimize(check);
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * f.pixels.size()));
  state.SetLabel(state.range(0) == 0 ? "portable" : fs::fw::detail::scan_row_u8_isa());
}
BENCHMARK(BM_ScanRow)->Arg(0)->Arg(1);

// The batched GaussMl fit alone: 8 stripe profiles (sigma 2.5 px, the cube frames' typical stripe) per call,
// 0 = the portable build (what arm runs, here SSE2), 1 = the one extraction uses (AVX-512VL or AVX2 when
// present), 2 = the AVX2 build, 3 = the one extraction uses, gauss-log (the first step alone).
// Items = rows fitted.
void BM_GaussMlBatch(benchmark::State& state) {
  fs::fw::detail::GaussMlBatch b;
  using fs::fw::detail::kBatch;
  using fs::fw::detail::kBatchHalf;
  for (int j = 0; j < kBatch; ++j) {
    const double u = -0.45 + 0.11 * j, s = 2.5;
    for (int x = -kBatchHalf; x < kBatchHalf; ++x)
      b.y[kBatchHalf + x][j] =
          static_cast<float>(150.0 * std::exp(-(x - u) * (x - u) / (2 * s * s)) + 0.3 * ((x * 7 + j) % 5));
    b.xa[j] = -10;
    b.xb[j] = 10;
    b.contrast[j] = 150.0;
    b.clip[j] = 200.0;
  }
  const fs::fw::detail::SensorNoise noise;
  b.intensity_step = state.range(0) != 3;
  if (state.range(0) == 2 && !fs::fw::detail::gauss_ml_centre_batch_avx2(b, noise)) {
    state.SkipWithError("no AVX2 here");
    return;
  }
  for (auto _ : state) {
    if (state.range(0) == 0)
      fs::fw::detail::gauss_ml_centre_batch_portable(b, noise);
    else if (state.range(0) == 2)
      fs::fw::detail::gauss_ml_centre_batch_avx2(b, noise);
    else
      fs::fw::detail::gauss_ml_centre_batch(b, noise);
    benchmark::DoNotOptimize(b.centre);
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kBatch));
  state.SetLabel(state.range(0) == 0   ? "portable"
                 : state.range(0) == 2 ? "avx2"
                                       : std::string(fs::fw::detail::gauss_ml_batch_isa()) +
                                             (state.range(0) == 3 ? ", gauss-log" : ""));
}
BENCHMARK(BM_GaussMlBatch)->Arg(0)->Arg(1)->Arg(2)->Arg(3);

BENCHMARK(BM_Extract)->Arg(0)->Arg(1)->Arg(2)->Arg(3)->Arg(4)->Arg(5);

// The default method with the along-stripe refinement over 0 (off), 5, 7 or 15 rows
// (ExtractParams::along_stripe; 15 is the default).
void BM_ExtractAlongStripe(benchmark::State& state) {
  Frame& f = frame();
  fs::fw::ExtractParams p;
  p.along_stripe = static_cast<std::uint32_t>(state.range(0));
  std::vector<fs::msg::StripePoint> out(f.view.height);
  for (auto _ : state) {
    fs::fw::extract_frame(f.view, p, out);
    benchmark::DoNotOptimize(out.data());
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * f.pixels.size()));
  state.SetLabel(std::string(fs::fw::to_string(p.method)) + ", along_stripe " +
                 std::to_string(p.along_stripe));
}
BENCHMARK(BM_ExtractAlongStripe)->Arg(0)->Arg(5)->Arg(7)->Arg(15);

}  // namespace

BENCHMARK_MAIN();
