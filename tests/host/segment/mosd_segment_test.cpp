// Real Kinect box scans (mOSD, ../shared/data/mosd-boxes): regions must not span two labelled objects.
#include <gtest/gtest.h>

#include "host/io/load.hpp"
#include "host/segment/quality.hpp"
#include "host/segment/scene_pfrg.hpp"
#include "host/segment/segmenter.hpp"
#include "support/test_paths.hpp"

namespace {

using namespace fs::host;

class MosdSegment : public ::testing::TestWithParam<const char*> {};

TEST_P(MosdSegment, RegionsStayWithinOneObject) {
  const auto path = fs::test::shared_data() / "mosd-boxes/test" / GetParam();
  OrganizedCloud cloud;
  load_cloud(path.string(), cloud);
  ASSERT_EQ(cloud.labels.size(), cloud.points.size());
  seg::Segmenter segmenter(seg::SegmentParams::kinect());
  seg::Segmentation s;
  segmenter.segment(cloud, s);
  std::vector<std::int32_t> obj(cloud.labels.size());
  for (std::size_t i = 0; i < obj.size(); ++i) obj[i] = seg::mosd_object(cloud.labels[i]);
  const auto span = seg::object_span(obj, s);
  EXPECT_GE(span.pure_fraction(), 0.95) << span.pure_regions << "/" << span.regions << " regions pure";
  EXPECT_GE(span.regions, 5);  // table + at least two faces of each of two boxes
  seg::ScenePfrgBuilder builder;
  Pfrg g;
  builder.build(s, g);
  EXPECT_EQ(g.nodes.size(), s.known_count() + 1);
  for (const auto& n : g.nodes) {
    if (n.supernode) continue;
    // Kinect camera frame: the sensor is at the origin looking along +z; faces point back toward it.
    EXPECT_LT(n.normal.dot(n.centroid), 0.0) << "node " << n.id;
  }
}

// Two boxes (test0, with the table), three boxes (test11), stacked boxes (test16, test21: the worst one).
INSTANTIATE_TEST_SUITE_P(Scenes, MosdSegment,
                         ::testing::Values("test0.pcd", "test11.pcd", "test16.pcd", "test21.pcd"));

}  // namespace
