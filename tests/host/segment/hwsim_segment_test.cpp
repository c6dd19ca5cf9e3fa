// Segmentation and scene PFRG on hw-sim ground-truth scans (bench-top scanner, 0.05 mm depth noise).
#include <gtest/gtest.h>

#include "hwsim_eval.hpp"
#include "support/segment_by_cells.hpp"
#include "support/test_paths.hpp"

namespace {

using fs::test::evaluate_hwsim_scene;

fs::test::HwsimEval eval(const char* name) {
  return evaluate_hwsim_scene(fs::test::source_dir() / "hw-sim/scenes" / (std::string(name) + ".json"), 0.05);
}

void expect_faces_and_graph(const fs::test::HwsimEval& ev, std::size_t visible_faces) {
  for (const auto& p : ev.problems) ADD_FAILURE() << p;
  EXPECT_EQ(ev.significant.size(), visible_faces) << "visible faces incl. the table";
  EXPECT_EQ(ev.significant_correct, int(ev.significant.size()));
  EXPECT_LT(ev.max_normal_error_deg, 1.0);
  // PFRG: exactly the visible faces (+ table) + supernode, with the true adjacencies
  EXPECT_EQ(ev.graph.nodes.size(), visible_faces + 1);
  EXPECT_EQ(ev.actual_arcs, ev.expected_arcs);
  std::size_t sn_arcs = 0;
  for (const auto& a : ev.graph.arcs) sn_arcs += (a.a == 0 || a.b == 0) ? 1 : 0;
  EXPECT_GE(sn_arcs, 1u);
}

TEST(HwsimSegment, TruncatedPyramid) {
  const auto ev = eval("pyramid");
  expect_faces_and_graph(ev, 5);  // table + top + the 3 sides the laser reaches
}

TEST(HwsimSegment, Cube) {
  const auto ev = eval("cube");
  expect_faces_and_graph(ev, 4);  // table + top + 2 sides
}

TEST(HwsimSegment, CubeOccludesPyramid) {
  const auto ev = eval("cube-occludes-pyramid");
  expect_faces_and_graph(ev, 7);  // table + 3 cube faces + 3 pyramid faces
}

// The demo scene: a wedge leaning on a cube, a truncated pyramid next to a hexagonal prism. The faces seen at
// a grazing angle (cube front 1002, wedge front 2000, prism side 4003: ~2.6 mm^2 per cell) used to take
// strips of the neighbouring table / top cells that lie within the distance tolerance of both planes near the
// crease (Hoover: "missed", 11/14); the boundary relabelling gives those cells to the nearer plane.
TEST(HwsimSegment, DemoSceneAllFacesIncludingGrazingOnes) {
  const auto ev = eval("default");
  expect_faces_and_graph(ev, 14);  // table + 13 object faces
  for (std::int32_t face : {1002, 2000, 4003}) EXPECT_TRUE(ev.hoover.gt_correct_region.count(face)) << face;
}

// The demo scene swept with 250 and 125 galvo steps (1.2 and 2.4 mm apart on the table; 500 steps: 0.6 mm).
// On the faces the laser meets at a grazing angle the steps lie several mm apart: with the jump threshold of
// jump_abs_mm alone some of them counted as depth jumps, and normals over 2 cells reached across the faces
// lit only a few columns wide. The thresholds and spans now follow the scan's grid spacing.
TEST(HwsimSegment, CoarseSweepsKeepEveryFace) {
  const auto scene = fs::test::source_dir() / "hw-sim/scenes/default.json";
  for (std::uint32_t steps : {250u, 125u}) {
    const auto ev = evaluate_hwsim_scene(scene, 0.05, 0.02, 7, steps);
    EXPECT_NEAR(ev.seg.spacing_mm.x(), 310.0 / steps, 0.25 * 310.0 / steps) << steps;  // along the sweep
    for (const auto& p : ev.problems) ADD_FAILURE() << steps << ": " << p;
    EXPECT_EQ(ev.significant_correct, int(ev.significant.size())) << steps;
  }
  auto by_cells = fs::host::seg::SegmentParams::laser();
  fs::test::segment_by_cells(by_cells);
  const auto ev = evaluate_hwsim_scene(scene, 0.05, 0.02, 7, 125, by_cells);
  EXPECT_LT(ev.significant_correct, int(ev.significant.size()));
}

}  // namespace
