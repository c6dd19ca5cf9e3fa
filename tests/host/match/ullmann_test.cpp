// Exact matching (Ullmann): thesis table 6.8, cube column.
#include <gtest/gtest.h>

#include <set>
#include <vector>

#include "host/match/ullmann.hpp"

namespace {

using fs::host::Pfrg;
using fs::host::match::count_isomorphisms;
using fs::host::match::ExactMode;

// Non-attributed cube face graph: faces 1..6 = +x +y +z -x -y -z; adjacent unless opposite.
Pfrg cube_graph(int nodes = 6) {
  Pfrg g;
  g.name = "cube";
  for (int i = 1; i <= nodes; ++i) {
    fs::host::PfrgNode n;
    n.id = i;
    n.area = 1;
    n.normal = fs::Vec3::UnitZ();
    g.nodes.push_back(n);
  }
  for (int a = 1; a <= nodes; ++a)
    for (int b = a + 1; b <= nodes; ++b)
      if (b - a != 3) g.arcs.push_back({a, b, 1.0});
  return g;
}

TEST(Ullmann, CubeTable68) {
  const std::vector<std::uint64_t> expected = {6, 24, 48, 48, 48, 48};
  const Pfrg ref = cube_graph();
  for (int k = 1; k <= 6; ++k) {
    EXPECT_EQ(count_isomorphisms(cube_graph(k), ref, ExactMode::kInduced).count, expected[k - 1])
        << "test nodes 1.." << k;
    EXPECT_EQ(count_isomorphisms(cube_graph(k), ref, ExactMode::kMonomorphism).count, expected[k - 1]) << k;
  }
}

TEST(Ullmann, InducedVersusMonomorphism) {
  // Test graph: path 1-2-3 (no arc 1-3). Into the cube: induced needs 1 and 3 opposite; monomorphism not.
  Pfrg t = cube_graph(3);
  t.arcs = {{1, 2, 1.0}, {2, 3, 1.0}};
  const Pfrg ref = cube_graph();
  // induced: middle node 6 ways, ends = an opposite pair among the 4 neighbours (2 pairs x 2 orders) = 24
  EXPECT_EQ(count_isomorphisms(t, ref, ExactMode::kInduced).count, 24u);
  // monomorphism: middle 6, ends any ordered pair of distinct neighbours 4*3 = 72
  EXPECT_EQ(count_isomorphisms(t, ref, ExactMode::kMonomorphism).count, 72u);
}

TEST(Ullmann, ListedMappingsArePreservingAndDistinct) {
  const Pfrg ref = cube_graph();
  const Pfrg t = cube_graph(3);
  std::set<std::vector<int>> seen;
  auto st = count_isomorphisms(t, ref, ExactMode::kInduced, [&](std::span<const std::pair<int, int>> m) {
    std::vector<int> img;
    for (auto [a, b] : m) img.push_back(b);
    // all three images pairwise adjacent (not opposite)
    for (std::size_t i = 0; i < img.size(); ++i)
      for (std::size_t j = i + 1; j < img.size(); ++j) EXPECT_NE(std::abs(img[i] - img[j]), 3);
    seen.insert(img);
  });
  EXPECT_EQ(st.count, 48u);
  EXPECT_EQ(seen.size(), 48u);
}

TEST(Ullmann, SupernodesIgnoredAndLargerTestGivesZero) {
  Pfrg t = cube_graph(6);
  fs::host::PfrgNode sn;
  sn.id = 99;
  sn.supernode = true;
  t.nodes.push_back(sn);
  t.arcs.push_back({1, 99, 3.0});
  EXPECT_EQ(count_isomorphisms(t, cube_graph(), ExactMode::kInduced).count, 48u);
  EXPECT_EQ(count_isomorphisms(cube_graph(6), cube_graph(5), ExactMode::kInduced).count, 0u);
}

}  // namespace
