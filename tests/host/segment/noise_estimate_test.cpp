// The segmenter's depth-noise estimate and the distance tolerance it can set (segment_params.hpp:
// dist_noise_factor, off in the presets), and what the laser tolerance is for: two faces meeting at a 5.3
// degree crease (an augmented hexagonal prism's pyramid on its square) stay two regions.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>

#include "host/io/organized_cloud.hpp"
#include "host/segment/segmenter.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/scene.hpp"
#include "support/test_paths.hpp"

namespace {

using fs::host::seg::Segmentation;
using fs::host::seg::SegmentParams;

fs::sim::Scene empty_scene(std::uint32_t steps) {
  fs::sim::Scene scene = fs::sim::load_scene(fs::test::source_dir() / "hw-sim/scenes/cube.json");
  scene.objects.clear();
  fs::sim::resample_sweep(scene.calibration, steps);
  return scene;
}

Segmentation segment(const fs::sim::Scene& scene, double noise_mm, const SegmentParams& params,
                     fs::host::OrganizedCloud& cloud) {
  fs::sim::make_ground_truth_grid(scene, {.depth_noise_mm = noise_mm, .seed = 11}).export_to(cloud, true);
  fs::host::seg::SegmentLimits lim;
  lim.max_cells = cloud.points.size();
  fs::host::seg::Segmenter segmenter(params, lim);
  Segmentation seg;
  segmenter.segment(cloud, seg);
  return seg;
}

TEST(NoiseEstimate, FollowsTheScansDepthNoise) {
  fs::sim::Scene scene = fs::sim::load_scene(fs::test::source_dir() / "hw-sim/scenes/cube.json");
  fs::sim::resample_sweep(scene.calibration, 200);
  fs::host::OrganizedCloud cloud;
  SegmentParams following = SegmentParams::laser();
  following.dist_noise_factor = 6.0;
  for (const double sigma : {0.05, 0.1, 0.2, 0.4}) {
    const Segmentation seg = segment(scene, sigma, following, cloud);
    // The noise is along the viewing ray and the camera looks down at the table and the cube's top: the
    // component across the rows' tangents is nearly all of it.
    EXPECT_NEAR(seg.noise_mm, sigma, 0.2 * sigma) << "sigma " << sigma;
    std::printf("depth noise %.3f mm: estimated %.4f mm, tolerance %.3f mm\n", sigma, seg.noise_mm,
                seg.dist_mm);
    EXPECT_DOUBLE_EQ(seg.dist_mm, std::max(0.3, 6.0 * seg.noise_mm));
  }
  const Segmentation exact = segment(scene, 0.0, following, cloud);
  EXPECT_LT(exact.noise_mm, 0.005);
  EXPECT_DOUBLE_EQ(exact.dist_mm, 0.3);
  // The presets keep their fixed tolerance (dist_noise_factor 0) but still report the noise.
  const Segmentation fixed = segment(scene, 0.4, SegmentParams::laser(), cloud);
  EXPECT_DOUBLE_EQ(fixed.dist_mm, 0.3);
  EXPECT_NEAR(fixed.noise_mm, 0.4, 0.08);
  EXPECT_DOUBLE_EQ(segment(scene, 0.4, SegmentParams::kinect(), cloud).dist_mm,
                   SegmentParams::kinect().dist_abs_mm);
}

// A 60 x 40 mm block whose top is two faces meeting along y at 5.26 degrees (each tilted 2.63 degrees).
fs::Mesh creased_block() {
  const double a = 30, b = 20, h = 20, rise = a * std::tan(2.63 * M_PI / 180.0);
  fs::Mesh m;
  m.name = "creased";
  m.vertices = {{-a, -b, 0},       {a, -b, 0},      {a, b, 0}, {-a, b, 0},  // 0-3 bottom
                {-a, -b, h},       {a, -b, h},      {a, b, h}, {-a, b, h},  // 4-7 top corners
                {0, -b, h + rise}, {0, b, h + rise}};                       // 8-9 ridge
  m.faces = {{0, 3, 2, 1},                                                  // bottom
             {4, 8, 9, 7},                                                  // left roof
             {8, 5, 6, 9},                                                  // right roof
             {0, 1, 5, 8, 4},                                               // front (y = -b)
             {2, 3, 7, 9, 6},                                               // back (y = +b)
             {1, 2, 6, 5},                                                  // right (x = +a)
             {3, 0, 4, 7}};                                                 // left (x = -a)
  return m;
}

TEST(NoiseEstimate, LaserToleranceKeepsAFiveDegreeCreaseAsTwoFaces) {
  fs::sim::Scene scene = empty_scene(300);
  fs::sim::add_object(scene, creased_block(), fs::Mat3::Identity(), fs::Vec3(0, 0, 0));
  fs::host::OrganizedCloud cloud;
  const Segmentation seg = segment(scene, 0.05, SegmentParams::laser(), cloud);
  // Ground-truth labels are object * 1000 + face: faces 1 and 2 are the two roof halves.
  auto regions_of = [&](std::int32_t label) {
    std::map<std::int32_t, int> count;
    int total = 0;
    for (std::size_t i = 0; i < cloud.labels.size(); ++i)
      if (cloud.labels[i] == label) {
        ++total;
        if (seg.labels[i] >= 0) ++count[seg.labels[i]];
      }
    std::int32_t best = -1;
    int best_n = 0;
    for (const auto& [r, n] : count)
      if (n > best_n) best = r, best_n = n;
    return std::pair{best, total > 0 ? double(best_n) / total : 0.0};
  };
  const auto [left, left_share] = regions_of(1001);
  const auto [right, right_share] = regions_of(1002);
  ASSERT_GE(left, 0);
  ASSERT_GE(right, 0);
  EXPECT_NE(left, right) << "the two roof faces were merged";
  EXPECT_GT(left_share, 0.9);
  EXPECT_GT(right_share, 0.9);
  // At the old 0.6 mm tolerance the region of one roof half grows over the crease.
  SegmentParams loose = SegmentParams::laser();
  loose.dist_abs_mm = 0.6;
  const Segmentation merged = segment(scene, 0.05, loose, cloud);
  int roof_regions_with_both = 0;
  std::map<std::int32_t, std::pair<int, int>> per_region;
  for (std::size_t i = 0; i < cloud.labels.size(); ++i) {
    if (merged.labels[i] < 0) continue;
    if (cloud.labels[i] == 1001) ++per_region[merged.labels[i]].first;
    if (cloud.labels[i] == 1002) ++per_region[merged.labels[i]].second;
  }
  for (const auto& [r, n] : per_region) roof_regions_with_both += (n.first > 200 && n.second > 200) ? 1 : 0;
  EXPECT_EQ(roof_regions_with_both, 1);
}

}  // namespace
