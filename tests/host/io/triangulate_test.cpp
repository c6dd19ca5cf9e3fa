// Triangulation: exactness against the double-precision reference, synthetic flat targets, grazing
// rejection, no allocation per scan after warm-up.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "common/alloc_counter/alloc_counter.hpp"
#include "host/io/scan.hpp"
#include "host/io/triangulate.hpp"
#include "synth_scan.hpp"

namespace fs::host {
namespace {

TEST(Triangulate, MatchesDoublePrecisionReference) {
  const auto calib = ScannerCalibration::bench_default(500);
  Triangulator tri(calib);
  OrganizedCloud cloud;
  tri.begin(cloud);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> col(0.0f, 1279.0f);
  msg::StripeHeader h;
  std::vector<msg::StripePoint> pts;
  TriangulationStats stats;
  for (std::uint32_t k = 0; k < 500; k += 37) {
    h.step_index = k;
    pts.clear();
    for (std::uint16_t r = 0; r < 1024; r += 13) pts.push_back(msg::StripePoint{r, col(rng), 100, 2.0f});
    tri.add_stripe(h, pts, cloud, stats);
    for (const auto& sp : pts) {
      Vec3 ref;
      const bool ok =
          Triangulator::triangulate_point(calib, k, sp.row, sp.col, std::sin(3.0 * M_PI / 180), ref);
      const auto& p = cloud.at(sp.row, k);
      ASSERT_EQ(ok, OrganizedCloud::valid(p)) << "row " << sp.row << " step " << k;
      if (ok) {
        EXPECT_LT((p.cast<double>() - ref).norm(), 2e-3)
            << "row " << sp.row << " col " << sp.col << " step " << k;
      }
    }
  }
  EXPECT_GT(stats.points, 500u);
}

TEST(Triangulate, FlatTargetsAreRecoveredExactly) {
  const auto calib = ScannerCalibration::bench_default(100);
  Triangulator tri(calib);
  for (double height : {0.0, 35.0, 80.0}) {
    const auto synth = fs::test::synth_flat_scan(calib, calib, height, 0.0, 1, 1, 2);
    Scan scan;
    fs::test::fill_scan(synth, scan);
    ASSERT_TRUE(scan.complete());
    OrganizedCloud cloud;
    const auto stats = tri.triangulate(scan, cloud);
    ASSERT_EQ(cloud.width, 100u);
    ASSERT_EQ(cloud.height, 1024u);
    EXPECT_GT(stats.points, 40000u);
    double sq = 0, worst = 0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < cloud.points.size(); ++i) {
      const auto& p = cloud.points[i];
      const auto& t = synth.truth.points[i];
      ASSERT_EQ(OrganizedCloud::valid(p), OrganizedCloud::valid(t)) << i;
      if (!OrganizedCloud::valid(p)) continue;
      const double e = (p - t).norm();
      sq += e * e;
      worst = std::max(worst, e);
      ++n;
    }
    EXPECT_LT(std::sqrt(sq / n), 1e-3) << "height " << height;
    EXPECT_LT(worst, 5e-3) << "height " << height;
  }
}

TEST(Triangulate, RejectsGrazingRays) {
  auto calib = ScannerCalibration::bench_default(100);
  // Put the laser axis right next to the camera: every ray then runs almost inside the laser plane.
  calib.laser.axis_point = calib.camera.t_world_cam + Vec3(1.0, 0, 0);
  TriangulationOptions strict;
  strict.min_ray_plane_angle_deg = 3.0;
  Triangulator tri(calib, strict);
  OrganizedCloud cloud;
  tri.begin(cloud);
  msg::StripeHeader h;
  h.step_index = 50;
  // The image trace of the laser plane: project a point of the plane below the axis.
  const Plane plane50 = calib.laser.plane_at_step(50);
  Vec3 in_plane = plane50.n.cross(calib.laser.axis_dir).normalized();
  if (in_plane.z() > 0) in_plane = -in_plane;
  Vec2 trace;
  ASSERT_TRUE(calib.camera.project(calib.laser.axis_point + 400.0 * in_plane, trace));
  std::vector<msg::StripePoint> pts;
  for (int dc = -300; dc <= 300; dc += 3)
    if (trace.x() + dc >= 0.0 && trace.x() + dc <= 1279.0)
      pts.push_back(msg::StripePoint{static_cast<std::uint16_t>(std::lround(trace.y())),
                                     static_cast<float>(trace.x() + dc), 100, 2.0f});
  TriangulationStats stats;
  tri.add_stripe(h, pts, cloud, stats);
  // Count what the reference says: ray-plane angle below 3 degrees.
  const Plane pl = calib.laser.plane_at_step(50);
  std::uint64_t expect_grazing = 0;
  for (const auto& sp : pts) {
    const Vec3 d = calib.camera.ray_world(Vec2(sp.col, sp.row));
    if (std::abs(pl.n.dot(d)) < std::sin(3.0 * M_PI / 180)) ++expect_grazing;
  }
  EXPECT_GT(expect_grazing, 10u);
  EXPECT_LT(expect_grazing, pts.size() - 10);
  EXPECT_EQ(stats.grazing, expect_grazing);
  // Every point is in the same image row: one cell, the others are counted as sharing it.
  EXPECT_EQ(stats.points, 1u);
  EXPECT_EQ(stats.points + stats.grazing + stats.out_of_range + stats.shared_cell, pts.size());
  // Point by point: a grazing ray leaves its cell empty, the others fill it.
  for (const auto& sp : pts) {
    const Vec3 d = calib.camera.ray_world(Vec2(sp.col, sp.row));
    const bool grazing = std::abs(pl.n.dot(d)) < std::sin(3.0 * M_PI / 180);
    tri.begin(cloud);
    TriangulationStats one;
    tri.add_stripe(h, std::span(&sp, 1), cloud, one);
    EXPECT_EQ(OrganizedCloud::valid(cloud.at(sp.row, 50)), !grazing && one.out_of_range == 0) << sp.col;
  }
}

TEST(Triangulate, SmoothingReducesNoiseButKeepsDepthJumps) {
  const auto calib = ScannerCalibration::bench_default(100);
  TriangulationOptions raw_opt;
  raw_opt.smooth_half_window = 0;
  Triangulator smooth(calib), raw(calib, raw_opt);
  // A straight stripe (col = 600 + 0.1 row) with noise, and a 6-pixel jump between rows 49 and 50.
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.0f, 0.2f);
  std::vector<msg::StripePoint> clean, noisy;
  for (std::uint16_t r = 0; r < 100; ++r) {
    const float c = 600.0f + 0.1f * r + (r >= 50 ? 6.0f : 0.0f);
    clean.push_back({r, c, 100, 2.0f});
    noisy.push_back({r, c + noise(rng), 100, 2.0f});
  }
  msg::StripeHeader h;
  h.step_index = 40;
  OrganizedCloud truth, a, b;
  TriangulationStats st;
  raw.begin(truth);
  raw.add_stripe(h, clean, truth, st);
  smooth.begin(a);
  smooth.add_stripe(h, noisy, a, st);
  raw.begin(b);
  raw.add_stripe(h, noisy, b, st);
  double ea = 0, eb = 0;
  for (std::uint16_t r = 0; r < 100; ++r) {
    ea += (a.at(r, 40) - truth.at(r, 40)).squaredNorm();
    eb += (b.at(r, 40) - truth.at(r, 40)).squaredNorm();
  }
  EXPECT_LT(ea, 0.4 * eb) << "smoothing over 5 rows should cut the squared error to ~1/5";
  // Noise-free: the rows next to the jump are not pulled across it.
  OrganizedCloud c;
  smooth.begin(c);
  smooth.add_stripe(h, clean, c, st);
  for (std::uint16_t r : {48, 49, 50, 51}) {
    EXPECT_LT((c.at(r, 40) - truth.at(r, 40)).norm(), 1e-3) << r;
  }
}

TEST(Triangulate, OutOfImageAndOutOfScanPointsAreCounted) {
  const auto calib = ScannerCalibration::bench_default(100);
  Triangulator tri(calib);
  OrganizedCloud cloud;
  tri.begin(cloud);
  TriangulationStats stats;
  msg::StripeHeader h;
  h.step_index = 10;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<msg::StripePoint> pts = {
      {5, -1.0f, 0, 0}, {5, 1279.5f, 0, 0}, {2000, 10.0f, 0, 0}, {6, nan, 0, 0}, {7, 600.0f, 0, 0}};
  tri.add_stripe(h, pts, cloud, stats);
  EXPECT_EQ(stats.out_of_image, 4u);
  EXPECT_EQ(stats.points, 1u);
  h.step_index = 100;  // beyond the scan's steps
  tri.add_stripe(h, pts, cloud, stats);
  EXPECT_EQ(stats.out_of_image, 9u);
}

TEST(Triangulate, NoAllocationPerScanAfterWarmUp) {
  const auto calib = ScannerCalibration::bench_default(120);
  const auto synth = fs::test::synth_flat_scan(calib, calib, 10.0, 0.05, 3);
  Scan scan;
  fs::test::fill_scan(synth, scan);
  Scan scan2;
  scan2.reserve(120, 120 * 1024);
  Triangulator tri(calib);
  OrganizedCloud cloud;
  cloud.reserve(120 * 1024);
  tri.triangulate(scan, cloud);  // warm-up
  fs::AllocCounter counter;
  for (int i = 0; i < 3; ++i) {
    fs::test::fill_scan(synth, scan2);  // Scan::start/add_stripe within capacity
    const auto st = tri.triangulate(scan2, cloud);
    EXPECT_GT(st.points, 100000u);
  }
  EXPECT_EQ(counter.allocations(), 0u);
}

}  // namespace
}  // namespace fs::host

// The full bench scan: 500 galvo steps x 1024 image rows (the benchmark's size), triangulated again and
// again into the same grid, and the scan itself refilled within its reserved storage: no allocation at all.
namespace fs::host {
namespace {

TEST(Triangulate, FullScan500x1024ReusesTheGridWithoutAllocating) {
  const auto calib = ScannerCalibration::bench_default(500);
  const auto synth = fs::test::synth_flat_scan(calib, calib, 20.0, 0.05, 4);
  std::size_t stripe_points = 0;
  for (const auto& st : synth.stripes) stripe_points += st.points.size();
  ASSERT_GT(stripe_points, 500u * 1000) << "nearly every row of every step has a stripe point";
  Scan scan;
  scan.reserve(500, stripe_points);
  Triangulator tri(calib);
  OrganizedCloud cloud;
  cloud.reserve(std::size_t(500) * 1024);
  fs::test::fill_scan(synth, scan);
  const auto warm = tri.triangulate(scan, cloud);  // warm-up (the smoothing scratch buffer)
  ASSERT_EQ(cloud.width, 500u);
  ASSERT_EQ(cloud.height, 1024u);
  fs::AllocCounter counter;
  for (int i = 0; i < 2; ++i) {
    fs::test::fill_scan(synth, scan);
    const auto st = tri.triangulate(scan, cloud);
    EXPECT_EQ(st.points, warm.points);
  }
  EXPECT_EQ(counter.allocations(), 0u);
  EXPECT_EQ(cloud.valid_count(), warm.points);
  EXPECT_GT(warm.points, 500u * 1000);
}

}  // namespace
}  // namespace fs::host
