// bench_segment: a 500 x 1024 organized grid (laser-scanner size) segmented and its scene PFRG built,
// single thread, after warm-up (no allocation per scan).
#include <benchmark/benchmark.h>

#include "host/segment/scene_pfrg.hpp"
#include "host/segment/segmenter.hpp"
#include "synthetic_scene.hpp"

namespace {

fs::test::SyntheticGrid& scene_grid() {
  static fs::test::SyntheticGrid g = [] {
    fs::test::SyntheticScene sc;
    sc.width = 500;
    sc.height = 1024;
    sc.focal = 1600;  // ~0.3 mm per cell at the table, like the bench-top scanner
    sc.table_half = 200;
    sc.objects.push_back(fs::test::make_pyramid({-40, -60, 0}, 35, 45, 15));
    sc.objects.push_back(fs::test::make_box({30, 50, 25}, {25, 25, 25}, 30));
    sc.objects.push_back(fs::test::make_box({-30, 90, 15}, {20, 12, 15}, -10));
    fs::test::SyntheticGrid grid;
    fs::test::render(sc, grid, 0.05);
    return grid;
  }();
  return g;
}

void BM_SegmentAndPfrg(benchmark::State& state) {
  auto& g = scene_grid();
  fs::host::seg::SegmentLimits lim;
  lim.max_cells = g.cloud.points.size();
  fs::host::seg::Segmenter seg(fs::host::seg::SegmentParams::laser(), lim);
  fs::host::seg::Segmentation s;
  seg.prepare(s);
  fs::host::seg::ScenePfrgBuilder b(lim.max_regions, lim.max_borders);
  fs::host::Pfrg pf;
  b.prepare(pf);
  for (auto _ : state) {
    seg.segment(g.cloud, s);
    b.build(s, pf);
    benchmark::DoNotOptimize(pf.arcs.data());
  }
  state.counters["known_regions"] = double(s.known_count());
  state.counters["nodes"] = double(pf.nodes.size());
  state.counters["arcs"] = double(pf.arcs.size());
  state.counters["cells"] = double(g.cloud.points.size());
}
BENCHMARK(BM_SegmentAndPfrg)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace

BENCHMARK_MAIN();
