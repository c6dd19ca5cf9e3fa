#include <gtest/gtest.h>

#include <cmath>

#include "common/calibration.hpp"

namespace {

TEST(Calibration, ProjectAndRayAreInverse) {
  const auto c = fs::ScannerCalibration::bench_default();
  const fs::Vec3 x(37.0, -52.0, 41.0);
  fs::Vec2 px;
  ASSERT_TRUE(c.camera.project(x, px));
  const fs::Vec3 ray = c.camera.ray_world(px);
  const fs::Vec3 expected = (x - c.camera.center()).normalized();
  EXPECT_LT((ray - expected).norm(), 1e-9);
}

TEST(Calibration, DefaultSweepCoversTable) {
  const auto c = fs::ScannerCalibration::bench_default(500);
  const fs::Vec3 down(0, 0, -1);
  for (std::uint32_t k : {0u, 499u}) {
    const fs::Plane p = c.laser.plane_at_step(k);
    // The plane contains the mirror axis.
    EXPECT_NEAR(p.signed_distance(c.laser.axis_point), 0.0, 1e-9);
    EXPECT_NEAR(p.signed_distance(c.laser.axis_point + 100 * c.laser.axis_dir), 0.0, 1e-9);
    // Where it meets the table line y = 0.
    const fs::Vec3 dir = p.n.cross(c.laser.axis_dir).normalized();
    fs::Vec3 hit;
    const fs::Vec3 d = dir.z() < 0 ? dir : fs::Vec3(-dir);
    ASSERT_TRUE(fs::intersect_ray_plane(c.laser.axis_point, d, c.table, 1e-6, hit));
    EXPECT_NEAR(hit.x(), k == 0 ? -150.0 : 150.0, 1e-6);
  }
}

TEST(Calibration, MirrorDoublesTheAngle) {
  const auto c = fs::ScannerCalibration::bench_default();
  const fs::Plane a = c.laser.plane_at_mirror_angle(0.0);
  const fs::Plane b = c.laser.plane_at_mirror_angle(0.01);
  EXPECT_NEAR(std::acos(std::clamp(a.n.dot(b.n), -1.0, 1.0)), 0.02, 1e-12);
}

TEST(Calibration, UndistortInvertsDistort) {
  auto cam = fs::ScannerCalibration::bench_default().camera;
  cam.p1 = 1e-3;
  cam.p2 = -5e-4;
  for (double u : {0.0, 300.0, 1279.0})
    for (double v : {0.0, 700.0, 1023.0}) {
      const fs::Vec2 xn = cam.undistort_pixel(fs::Vec2(u, v));
      const fs::Vec2 xd = cam.distort(xn);
      EXPECT_NEAR(cam.fx * xd.x() + cam.cx, u, 1e-6);
      EXPECT_NEAR(cam.fy * xd.y() + cam.cy, v, 1e-6);
    }
}

TEST(Calibration, StepThroughInvertsPlaneAtStep) {
  auto c = fs::ScannerCalibration::bench_default();
  for (int flip = 0; flip < 2; ++flip) {
    // A plane's normal has two signs: either one gives the same step.
    if (flip) c.laser.normal_at_zero = -c.laser.normal_at_zero;
    for (double k : {0.0, 17.5, 250.0, 499.0}) {
      const fs::Plane p = c.laser.plane_at_step(k);
      // Points of that plane at several heights and depths.
      const fs::Vec3 dir = p.n.cross(c.laser.axis_dir).normalized();
      for (double s : {200.0, 450.0, 600.0})
        for (double y : {-80.0, 0.0, 90.0}) {
          const fs::Vec3 x =
              c.laser.axis_point + s * (dir.z() < 0 ? dir : fs::Vec3(-dir)) + y * c.laser.axis_dir;
          EXPECT_NEAR(c.laser.step_through(x), k, 1e-6) << "flip " << flip << " step " << k;
        }
    }
  }
  EXPECT_TRUE(std::isnan(c.laser.step_through(c.laser.axis_point + 5.0 * c.laser.axis_dir)));
}

TEST(Calibration, CoversTheSameWhereverTheSweepsStepsStart) {
  // The same physical sweep, its steps numbered from 20000 (a quarter turn of plane angle is 7854 steps at
  // 1e-4 rad per step: beyond it, a fold around step 0 would pick the plane half a turn away).
  const auto c = fs::ScannerCalibration::bench_default();
  auto far = c;
  far.first_step = 20000;
  far.laser.mirror_angle_at_step0 = c.laser.mirror_angle_at_step0 - 20000 * c.laser.rad_per_step;
  for (double x : {-160.0, -149.0, -60.0, 0.0, 90.0, 149.0, 160.0})
    for (double z : {0.0, 40.0, 100.0}) {
      const fs::Vec3 p(x, 10.0, z);
      EXPECT_EQ(far.covers(p), c.covers(p)) << x << " " << z;
      EXPECT_NEAR(far.laser.step_through(p, 20250.0), c.laser.step_through(p, 250.0) + 20000.0, 1e-6);
    }
  EXPECT_TRUE(far.covers(fs::Vec3(0.0, 0.0, 0.0)));
}

TEST(Calibration, CoversWhatTheSweepAndTheImageReach) {
  const auto c = fs::ScannerCalibration::bench_default();
  // The table line the sweep covers (x in [-150, 150]) and just beyond it.
  EXPECT_TRUE(c.covers(fs::Vec3(-149.0, 0.0, 0.0)));
  EXPECT_TRUE(c.covers(fs::Vec3(149.0, 20.0, 0.0)));
  EXPECT_FALSE(c.covers(fs::Vec3(-152.0, 0.0, 0.0)));
  EXPECT_FALSE(c.covers(fs::Vec3(152.0, 0.0, 0.0)));
  // The mirror is at x = 200, z = 500: at 100 mm above the table the first plane is at x = -80.
  EXPECT_TRUE(c.covers(fs::Vec3(-78.0, 0.0, 100.0)));
  EXPECT_FALSE(c.covers(fs::Vec3(-82.0, 0.0, 100.0)));
  // Outside the camera image (1024 rows at 1600 px focal length, 500 mm: y within about +-160 mm).
  EXPECT_TRUE(c.covers(fs::Vec3(0.0, 150.0, 0.0)));
  EXPECT_FALSE(c.covers(fs::Vec3(0.0, 175.0, 0.0)));
  // Behind the camera.
  EXPECT_FALSE(c.covers(fs::Vec3(0.0, 0.0, 600.0)));
}

}  // namespace
