// Preprocessing of the scene PFRG (thesis ch. 3.5.2) on hand-made region/border representations.
#include <gtest/gtest.h>

#include "host/segment/scene_pfrg.hpp"

namespace {

using namespace fs::host;
using namespace fs::host::seg;

Region known_region(int id, double area, fs::Vec3 n) {
  Region r;
  r.id = id;
  r.known = true;
  r.area = area;
  r.plane.n = n.normalized();
  r.cells = 100;
  return r;
}
Region unknown_region(int id) {
  Region r;
  r.id = id;
  r.cells = 3;
  return r;
}
Border border(int a, int b, double len) {
  Border x;
  x.a = a;
  x.b = b;
  x.length = len;
  x.edges = 10;
  return x;
}
const PfrgArc* arc(const Pfrg& g, int a, int b) {
  for (const auto& x : g.arcs)
    if ((x.a == a && x.b == b) || (x.a == b && x.b == a)) return &x;
  return nullptr;
}

TEST(ScenePfrg, SupernodeCollectsNilAndImageBoundaryAndMergesParallelArcs) {
  Segmentation s;
  s.regions = {known_region(0, 100, {0, 0, 1}), known_region(1, 50, {1, 0, 1})};
  s.borders = {border(0, 1, 10), border(0, kNil, 4), border(0, kOutside, 6), border(1, kNil, 3)};
  Pfrg g;
  ScenePfrgBuilder().build(s, g);
  ASSERT_EQ(g.nodes.size(), 3u);
  EXPECT_TRUE(g.nodes[0].supernode);
  EXPECT_EQ(g.nodes[0].id, 0);
  EXPECT_EQ(g.nodes[1].id, 1);
  EXPECT_DOUBLE_EQ(g.nodes[1].area, 100);
  ASSERT_EQ(g.arcs.size(), 3u);
  ASSERT_NE(arc(g, 0, 1), nullptr);
  EXPECT_DOUBLE_EQ(arc(g, 0, 1)->border, 10.0);  // NIL 4 + image boundary 6 merged into one arc
  EXPECT_DOUBLE_EQ(arc(g, 1, 2)->border, 10.0);
  EXPECT_DOUBLE_EQ(arc(g, 0, 2)->border, 3.0);
}

TEST(ScenePfrg, BorderRegionCompressedOntoExistingBorder) {
  // R0 | thin unknown R2 | R1, with a short direct border R0-R1 existing; R2 touches NIL at its ends.
  Segmentation s;
  s.regions = {known_region(0, 100, {0, 0, 1}), known_region(1, 80, {1, 0, 1}), unknown_region(2)};
  s.borders = {border(0, 1, 5), border(0, 2, 30), border(1, 2, 32), border(2, kNil, 1)};
  Pfrg g;
  PreprocessStats st;
  ScenePfrgBuilder().build(s, g, &st);
  EXPECT_EQ(st.border_regions_eliminated, 1);
  ASSERT_EQ(g.nodes.size(), 3u);
  ASSERT_NE(arc(g, 1, 2), nullptr);
  EXPECT_DOUBLE_EQ(arc(g, 1, 2)->border, 5.0 + 31.0);
  EXPECT_EQ(arc(g, 0, 1), nullptr);  // the border region's NIL contact does not create arcs
}

TEST(ScenePfrg, BorderRegionWithoutExistingBorderIsNotBridged) {
  // No R0-R1 border: the strip may hide a jump edge, so R0 and R1 must not become adjacent.
  Segmentation s;
  s.regions = {known_region(0, 100, {0, 0, 1}), known_region(1, 80, {1, 0, 1}), unknown_region(2)};
  s.borders = {border(0, 2, 30), border(1, 2, 32), border(0, kNil, 7), border(1, kNil, 8)};
  Pfrg g;
  PreprocessStats st;
  ScenePfrgBuilder().build(s, g, &st);
  EXPECT_EQ(st.border_regions_eliminated, 0);
  EXPECT_EQ(arc(g, 1, 2), nullptr);
  EXPECT_EQ(st.null_nodes_dropped, 1);  // does not touch the unknown area: dropped with its arcs
  EXPECT_DOUBLE_EQ(arc(g, 0, 1)->border, 7.0);
}

TEST(ScenePfrg, BorderRegionWithThreeKnownNeighboursStaysANullNode) {
  Segmentation s;
  s.regions = {known_region(0, 100, {0, 0, 1}), known_region(1, 80, {1, 0, 1}),
               known_region(2, 70, {0, 1, 1}), unknown_region(3)};
  s.borders = {border(0, 1, 5), border(0, 3, 10), border(1, 3, 10), border(2, 3, 10), border(3, kNil, 2)};
  Pfrg g;
  PreprocessStats st;
  ScenePfrgBuilder().build(s, g, &st);
  EXPECT_EQ(st.border_regions_eliminated, 0);
  EXPECT_EQ(st.null_nodes_to_supernode, 1);  // touches NIL: part of the unknown area
  EXPECT_DOUBLE_EQ(arc(g, 1, 2)->border, 5.0);
  ASSERT_NE(arc(g, 0, 3), nullptr);
  EXPECT_DOUBLE_EQ(arc(g, 0, 3)->border, 10.0);
  EXPECT_DOUBLE_EQ(arc(g, 0, 1)->border, 10.0);
  EXPECT_EQ(g.nodes.size(), 4u);
}

TEST(ScenePfrg, HoleInsideAFaceLeavesNoArc) {
  Segmentation s;
  s.regions = {known_region(0, 100, {0, 0, 1}), unknown_region(1)};
  s.borders = {border(0, 1, 3), border(0, kOutside, 40)};
  Pfrg g;
  ScenePfrgBuilder().build(s, g);
  ASSERT_EQ(g.arcs.size(), 1u);
  EXPECT_DOUBLE_EQ(arc(g, 0, 1)->border, 40.0);
}

TEST(ScenePfrg, TinyBordersBetweenRegionsAreIgnored) {
  Segmentation s;
  s.regions = {known_region(0, 100, {0, 0, 1}), known_region(1, 80, {1, 0, 1})};
  s.borders = {border(0, 1, 1.2), border(0, kNil, 20)};
  s.borders[0].edges = 1;
  Pfrg g;
  ScenePfrgBuilder().build(s, g);
  EXPECT_EQ(arc(g, 1, 2), nullptr);
  EXPECT_NE(arc(g, 0, 1), nullptr);
}

TEST(ScenePfrg, EmptySegmentationGivesOnlyTheSupernode) {
  Segmentation s;
  Pfrg g;
  ScenePfrgBuilder().build(s, g);
  ASSERT_EQ(g.nodes.size(), 1u);
  EXPECT_TRUE(g.nodes[0].supernode);
  EXPECT_TRUE(g.arcs.empty());
}

}  // namespace
