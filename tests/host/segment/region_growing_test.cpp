// Region growing (breadth-first start, then scanline runs) on hand-made grids: a serpentine corridor that
// the runs must follow down and up again, walls of missing data that must not be crossed, and a depth step.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <set>

#include "host/segment/segmenter.hpp"

namespace {

using namespace fs::host;
using namespace fs::host::seg;

// Plane z = 0.1 x + 0.05 y sampled at 1 mm, viewpoint above; NaN walls at every 12th column, open alternately
// at the bottom and at the top (a serpentine corridor 11 cells wide, 10 bends).
OrganizedCloud serpentine(std::uint32_t w, std::uint32_t h, bool close_last_bend) {
  OrganizedCloud c;
  c.reset(w, h);
  c.viewpoint = fs::Vec3(w / 2.0, h / 2.0, 400.0);
  for (std::uint32_t r = 0; r < h; ++r)
    for (std::uint32_t k = 0; k < w; ++k)
      c.at(r, k) = Eigen::Vector3f(float(k), float(r), 0.1f * k + 0.05f * r);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  int wall = 0;
  for (std::uint32_t k = 12; k + 1 < w; k += 12, ++wall) {
    const bool open_at_bottom = wall % 2 == 0;
    const bool last = k + 12 + 1 >= w;
    for (std::uint32_t r = 0; r < h; ++r) {
      const bool gap = open_at_bottom ? r + 8 >= h : r < 8;
      if (!gap || (last && close_last_bend)) c.at(r, k) = Eigen::Vector3f(nan, nan, nan);
    }
  }
  return c;
}

std::set<std::int32_t> known_labels(const Segmentation& s) {
  std::set<std::int32_t> out;
  for (auto l : s.labels)
    if (l >= 0 && s.regions[std::size_t(l)].known) out.insert(l);
  return out;
}

TEST(RegionGrowing, FollowsASerpentineCorridorAsOneRegion) {
  const OrganizedCloud c = serpentine(133, 90, false);
  Segmenter seg;
  Segmentation s;
  seg.segment(c, s);
  std::size_t valid = 0, in_region = 0;
  const auto known = known_labels(s);
  ASSERT_EQ(known.size(), 1u) << "the corridor is one plane";
  const std::int32_t r = *known.begin();
  for (std::size_t i = 0; i < c.points.size(); ++i) {
    if (!c.points[i].allFinite()) continue;
    ++valid;
    in_region += s.labels[i] == r ? 1 : 0;
  }
  EXPECT_EQ(in_region, valid) << "every cell of the corridor, also behind all 10 bends";
  const auto& reg = s.regions[std::size_t(r)];
  const fs::Vec3 n = fs::Vec3(-0.1, -0.05, 1).normalized();
  EXPECT_GT(reg.plane.n.dot(n), std::cos(0.01 * M_PI / 180));
  // area of the plane per 1 x 1 mm cell: |(1,0,0.1) x (0,1,0.05)|
  EXPECT_NEAR(reg.area / double(valid), std::sqrt(1 + 0.01 + 0.0025), 0.02);
}

TEST(RegionGrowing, WallsOfMissingDataAreNotCrossed) {
  const OrganizedCloud c = serpentine(133, 90, true);  // the last corridor is closed off
  Segmenter seg;
  Segmentation s;
  seg.segment(c, s);
  const auto known = known_labels(s);
  ASSERT_EQ(known.size(), 2u);
  // the closed corridor (columns after the last wall) is its own region
  const std::int32_t a = s.labels[5 * c.width + 2], b = s.labels[5 * c.width + c.width - 3];
  EXPECT_GE(a, 0);
  EXPECT_GE(b, 0);
  EXPECT_NE(a, b);
}

TEST(RegionGrowing, DepthStepAlongTheRaySplitsCoplanarLookingHalves) {
  // two parallel planes 20 mm apart in depth (a jump along the viewing rays, not a grazing surface)
  OrganizedCloud c;
  c.reset(80, 60);
  c.viewpoint = fs::Vec3(40, 30, 400);
  for (std::uint32_t r = 0; r < 60; ++r)
    for (std::uint32_t k = 0; k < 80; ++k)
      c.at(r, k) = Eigen::Vector3f(float(k), float(r), k < 40 ? 0.f : 20.f);
  Segmenter seg;
  Segmentation s;
  seg.segment(c, s);
  ASSERT_EQ(known_labels(s).size(), 2u);
  EXPECT_NE(s.labels[30 * 80 + 10], s.labels[30 * 80 + 70]);
}

}  // namespace
