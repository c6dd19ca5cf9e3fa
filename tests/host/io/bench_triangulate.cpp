// Triangulation throughput: a full 500-step x 1024-row scan of a flat target (bench default geometry),
// triangulated into a preallocated organized cloud. Reports points/s (items_per_second).
#include <benchmark/benchmark.h>

#include "host/io/scan.hpp"
#include "host/io/triangulate.hpp"
#include "synth_scan.hpp"

namespace {

// range(0) = steps, range(1) = stripe smoothing half window (0 = off, 2 = default).
void BM_TriangulateScan(benchmark::State& state) {
  const auto calib = fs::ScannerCalibration::bench_default(static_cast<std::uint32_t>(state.range(0)));
  const auto synth = fs::test::synth_flat_scan(calib, calib, 20.0, 0.05, 1);
  fs::host::Scan scan;
  fs::test::fill_scan(synth, scan);
  fs::host::TriangulationOptions opt;
  opt.smooth_half_window = static_cast<std::uint32_t>(state.range(1));
  fs::host::Triangulator tri(calib, opt);
  fs::host::OrganizedCloud cloud;
  cloud.reserve(std::size_t(calib.step_count) * calib.camera.height);
  std::uint64_t points = 0;
  for (auto _ : state) {
    const auto st = tri.triangulate(scan, cloud);
    points += st.points;
    benchmark::DoNotOptimize(cloud.points.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(points));
  state.counters["points_per_scan"] = double(points) / double(state.iterations());
}
BENCHMARK(BM_TriangulateScan)->Args({500, 2})->Args({500, 0})->Unit(benchmark::kMillisecond);

// The stripe loop alone (cloud reset excluded): one stripe of 1024 points at a time.
void BM_TriangulateStripes(benchmark::State& state) {
  const auto calib = fs::ScannerCalibration::bench_default(500);
  const auto synth = fs::test::synth_flat_scan(calib, calib, 20.0, 0.05, 1);
  fs::host::Triangulator tri(calib);
  fs::host::OrganizedCloud cloud;
  tri.begin(cloud);
  fs::host::TriangulationStats st;
  for (auto _ : state) {
    for (const auto& s : synth.stripes) tri.add_stripe(s.header, s.points, cloud, st);
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(st.points));
}
BENCHMARK(BM_TriangulateStripes)->Unit(benchmark::kMillisecond);

// One-off cost of configure() (ray table for 1280 x 1024 + step planes).
void BM_Configure(benchmark::State& state) {
  const auto calib = fs::ScannerCalibration::bench_default(500);
  for (auto _ : state) {
    fs::host::Triangulator tri(calib);
    benchmark::DoNotOptimize(&tri);
  }
}
BENCHMARK(BM_Configure)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
