// Zero heap allocations per scan after warm-up (segmentation + scene PFRG), with fs::AllocCounter.
#include <gtest/gtest.h>

#include "common/alloc_counter/alloc_counter.hpp"
#include "common/error.hpp"
#include "host/segment/scene_pfrg.hpp"
#include "host/segment/segmenter.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "support/test_paths.hpp"
#include "synthetic_scene.hpp"

namespace {

using namespace fs::host;
using namespace fs::host::seg;

// Segmenter + scene PFRG builder with their outputs prepared once, held the way the recognizer holds them.
struct SegmentPipeline {
  explicit SegmentPipeline(const SegmentLimits& lim)
      : segmenter(SegmentParams::laser(), lim), builder(lim.max_regions, lim.max_borders) {
    segmenter.prepare(s);
    builder.prepare(g);
  }
  void run(const OrganizedCloud& cloud) {
    segmenter.segment(cloud, s);
    builder.build(s, g);
  }
  Segmenter segmenter;
  Segmentation s;
  ScenePfrgBuilder builder;
  Pfrg g;
};

TEST(SegmentAlloc, NoAllocationPerScanAfterWarmUp) {
  fs::test::SyntheticScene sc;
  sc.objects.push_back(fs::test::make_pyramid({-30, 10, 0}, 35, 40, 25));
  sc.objects.push_back(fs::test::make_box({45, -20, 20}, {20, 15, 20}, -15));
  fs::test::SyntheticGrid a, b;
  fs::test::render(sc, a, 0.05, 1);
  sc.objects[1] = fs::test::make_box({40, 30, 15}, {15, 25, 15}, 40);  // a different second scan
  fs::test::render(sc, b, 0.05, 2);

  SegmentLimits lim;
  lim.max_cells = a.cloud.points.size();
  lim.max_regions = 2048;
  lim.max_borders = 8192;
  SegmentPipeline p(lim);
  p.run(a.cloud);  // warm-up

  fs::AllocCounter counter;
  p.run(b.cloud);
  p.run(a.cloud);
  EXPECT_EQ(counter.allocations(), 0u);
  EXPECT_GE(p.g.nodes.size(), 7u);  // the work was done: SN + table + >= 5 faces
}

// The realistic case: full-size bench-scanner scans (500 galvo steps x 1024 rows) of the hw-sim scenes, with
// the segmenter / builder set up the way the recognizer does it (one per process, limits from the grid size).
// Warm-up on the simplest scene; then the 4-object demo scene (more regions, borders, runs, relabelled cells)
// runs without a single heap allocation, twice (the second time over the first one's leftovers).
TEST(SegmentAlloc, NoAllocationPerHwsimScanAfterWarmUp) {
  auto scan = [](const char* name, std::uint64_t seed) {
    const auto gt = fs::sim::make_ground_truth_grid(fs::test::source_dir() / "hw-sim/scenes" / name,
                                                    {.depth_noise_mm = 0.05, .seed = seed});
    OrganizedCloud c;
    gt.export_to(c, true);
    return c;
  };
  const OrganizedCloud warm = scan("cube.json", 1), demo = scan("default.json", 2);
  ASSERT_EQ(warm.points.size(), demo.points.size());
  ASSERT_GE(demo.points.size(), 500u * 1024u);

  SegmentLimits lim;
  lim.max_cells = warm.points.size();
  SegmentPipeline p(lim);
  p.run(warm);
  const std::size_t warm_nodes = p.g.nodes.size();

  fs::AllocCounter counter;
  p.run(demo);
  const std::size_t demo_nodes = p.g.nodes.size(), demo_arcs = p.g.arcs.size();
  p.run(warm);
  p.run(demo);
  EXPECT_EQ(counter.allocations(), 0u);
  EXPECT_FALSE(p.s.truncated);
  // the work was done: table + 13 object faces + supernode in the demo scene, more than in the warm-up scene
  EXPECT_EQ(demo_nodes, 15u);
  EXPECT_GE(demo_arcs, 29u);
  EXPECT_GT(demo_nodes, warm_nodes);
  EXPECT_EQ(p.g.nodes.size(), demo_nodes);
  EXPECT_EQ(p.g.arcs.size(), demo_arcs);
}

TEST(SegmentLimits, RegionBudgetExhaustionIsFlaggedNotFatal) {
  // A staircase of many small planes with a tiny region budget.
  OrganizedCloud c;
  c.reset(120, 60);
  c.viewpoint = fs::Vec3(60, 30, 400);
  for (std::uint32_t r = 0; r < 60; ++r)
    for (std::uint32_t k = 0; k < 120; ++k)
      c.at(r, k) = Eigen::Vector3f(float(k), float(r), float((k / 10) * 8));
  SegmentLimits lim;
  lim.max_cells = c.points.size();
  lim.max_regions = 4;
  lim.max_borders = 16;
  Segmenter segmenter(SegmentParams::laser(), lim);
  Segmentation s;
  segmenter.segment(c, s);
  EXPECT_TRUE(s.truncated);
  EXPECT_LE(s.regions.size(), 4u);
  ScenePfrgBuilder builder(lim.max_regions, lim.max_borders);
  Pfrg g;
  builder.build(s, g);
  EXPECT_GE(g.nodes.size(), 2u);
}

TEST(SegmentInput, MismatchedGridIsAnError) {
  OrganizedCloud c;
  c.width = 10;
  c.height = 10;
  c.points.resize(50);
  Segmenter segmenter;
  Segmentation s;
  EXPECT_THROW(segmenter.segment(c, s), fs::Error);
}

TEST(SegmentInput, AllNanAndEmptyGridsGiveOnlyTheSupernode) {
  Segmenter segmenter;
  ScenePfrgBuilder builder;
  for (std::uint32_t w : {0u, 37u}) {
    OrganizedCloud c;
    c.reset(w, w ? 23 : 0);
    Segmentation s;
    segmenter.segment(c, s);
    EXPECT_TRUE(s.regions.empty());
    Pfrg g;
    builder.build(s, g);
    ASSERT_EQ(g.nodes.size(), 1u);
    EXPECT_TRUE(g.arcs.empty());
  }
}

}  // namespace
