// Hoover et al. 1996 classification and the object-span measure on hand-made label images.
#include <gtest/gtest.h>

#include "host/segment/quality.hpp"

namespace {

using namespace fs::host::seg;

Segmentation machine(std::vector<std::int32_t> labels, int regions) {
  Segmentation s;
  s.width = std::uint32_t(labels.size());
  s.height = 1;
  s.labels = std::move(labels);
  for (int r = 0; r < regions; ++r) {
    Region g;
    g.id = r;
    g.known = true;
    g.area = 1;
    g.plane.n = fs::Vec3::UnitZ();
    s.regions.push_back(g);
  }
  return s;
}

TEST(Hoover, ClassifiesCorrectOverUnderMissedNoise) {
  // GT:  A A A A A A A A A A | B B B B B B B B B B | C C C C C C C C C C | D D D D D D D D D D | E E E E
  // MS:  0 0 0 0 0 0 0 0 0 0 | 1 1 1 1 1 2 2 2 2 2 | 3 3 3 3 3 3 3 3 3 3   3 3 3 3 3 3 3 3 3 3 | - - - -
  // plus a machine region 4 on unlabelled cells (noise).
  std::vector<std::int32_t> gt, ms;
  for (int i = 0; i < 10; ++i) {
    gt.push_back(10);
    ms.push_back(0);
  }
  for (int i = 0; i < 10; ++i) {
    gt.push_back(11);
    ms.push_back(i < 5 ? 1 : 2);
  }
  for (int i = 0; i < 10; ++i) {
    gt.push_back(12);
    ms.push_back(3);
  }
  for (int i = 0; i < 10; ++i) {
    gt.push_back(13);
    ms.push_back(3);
  }
  for (int i = 0; i < 4; ++i) {
    gt.push_back(14);
    ms.push_back(kNil);
  }
  for (int i = 0; i < 6; ++i) {
    gt.push_back(-1);
    ms.push_back(4);
  }
  const Segmentation s = machine(ms, 5);
  const auto r = hoover_compare(gt, s, 0.8, [](std::int32_t) -> std::optional<fs::Vec3> {
    return fs::Vec3(0, std::sin(0.01), std::cos(0.01));
  });
  EXPECT_EQ(r.gt_regions, 5);
  EXPECT_EQ(r.correct, 1);
  EXPECT_EQ(r.over, 1);
  EXPECT_EQ(r.under, 1);
  EXPECT_EQ(r.missed, 1);
  EXPECT_EQ(r.noise, 1);
  EXPECT_EQ(r.gt_class.at(10), HooverClass::Correct);
  EXPECT_EQ(r.gt_class.at(11), HooverClass::Over);
  EXPECT_EQ(r.gt_class.at(14), HooverClass::Missed);
  EXPECT_NEAR(r.mean_angle_error_deg, 0.01 * 180 / 3.14159265358979323846, 1e-9);
}

TEST(Hoover, ToleranceDecidesCorrectness) {
  // machine region covers 85% of the GT region: correct at T = 0.8, missed + noise at T = 0.9.
  std::vector<std::int32_t> gt(20, 10), ms(20, 0);
  for (int i = 17; i < 20; ++i) ms[std::size_t(i)] = kNil;
  const Segmentation s = machine(ms, 1);
  EXPECT_EQ(hoover_compare(gt, s, 0.8).correct, 1);
  const auto strict = hoover_compare(gt, s, 0.9);
  EXPECT_EQ(strict.correct, 0);
  EXPECT_EQ(strict.missed, 1);
  EXPECT_EQ(strict.noise, 1);
}

TEST(ObjectSpan, CountsRegionsSpanningTwoObjectsByArea) {
  std::vector<std::int32_t> obj = {1, 1, 1, 1, 2, 2, 2, 2, 2, 2};
  Segmentation s = machine({0, 0, 0, 0, 1, 1, 1, 1, 1, 1}, 2);
  EXPECT_DOUBLE_EQ(object_span(obj, s).pure_fraction(), 1.0);
  s = machine({0, 0, 0, 0, 0, 1, 1, 1, 1, 1}, 2);
  s.regions[0].area = 3;
  const auto sp = object_span(obj, s);
  EXPECT_EQ(sp.regions, 2);
  EXPECT_EQ(sp.pure_regions, 1);
  EXPECT_DOUBLE_EQ(sp.pure_fraction(), 1.0 / 4.0);
  EXPECT_EQ(mosd_object(0), -1);
  EXPECT_EQ(mosd_object(3), 0);
  EXPECT_EQ(mosd_object(31), 3);
}

}  // namespace
