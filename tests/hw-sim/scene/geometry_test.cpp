// Laser plane geometry, ray casting, visibility and the ground-truth grid, checked against independent ray
// casts.
#include <gtest/gtest.h>

#include <limits>
#include <optional>

#include <cmath>

#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/oblique_rig.hpp"
#include "hw-sim/scene/ray_cast.hpp"
#include "hw-sim/scene/stripe_tracer.hpp"
#include "support/test_paths.hpp"

namespace {

using fs::Vec2;
using fs::Vec3;

fs::sim::Scene scene_file(const char* name, std::uint32_t steps = 0) {
  fs::sim::Scene s =
      fs::sim::load_scene(fs::test::source_dir() / "hw-sim/scenes" / (std::string(name) + ".json"));
  if (steps > 0) fs::sim::resample_sweep(s.calibration, steps);  // fewer steps, same sweep: fast tests
  return s;
}

// The bench scanner has the mirror at the camera's height, so every laser ray images onto one row (rows are
// epipolar lines) and a shadowed point always shares its row with the point that shadows it. A mirror lower
// than the camera breaks that symmetry, so shadows and occlusions must be resolved by the visibility tests.
void lower_the_mirror(fs::sim::Scene& s, double z = 300.0) {
  auto& L = s.calibration.laser;
  L.axis_point = Vec3(220, 0, z);
  const Vec3 to_origin = (-L.axis_point).normalized();
  L.normal_at_zero = L.axis_dir.cross(to_origin).normalized();
  auto angle_for_x = [&](double x) {
    const Vec3 dir = (Vec3(x, 0, 0) - L.axis_point).normalized();
    return std::atan2(to_origin.cross(dir).dot(L.axis_dir), to_origin.dot(dir)) / L.optical_gain;
  };
  L.mirror_angle_at_step0 = angle_for_x(-150);
  L.rad_per_step = (angle_for_x(150) - L.mirror_angle_at_step0) / (s.calibration.step_count - 1);
}

fs::sim::Scene cube_at(const Vec3& t, double edge = 50.0) {
  fs::Mesh m;
  m.name = "cube";
  const double h = edge / 2;
  m.vertices = {{-h, -h, 0},    {h, -h, 0},    {h, h, 0},    {-h, h, 0},
                {-h, -h, edge}, {h, -h, edge}, {h, h, edge}, {-h, h, edge}};
  m.faces = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
  fs::sim::Scene s;
  s.source = "test";
  fs::sim::add_object(s, m, fs::Mat3::Identity(), t);
  return s;
}

TEST(LaserGeometry, PlaneFromMirrorAngle) {
  const auto c = fs::ScannerCalibration::bench_default(500);
  const auto& L = c.laser;
  // The plane always contains the mirror axis.
  for (double a : {-0.2, -0.05, 0.0, 0.1}) {
    const fs::Plane p = L.plane_at_mirror_angle(a);
    EXPECT_NEAR(p.n.norm(), 1.0, 1e-12);
    EXPECT_NEAR(p.signed_distance(L.axis_point), 0.0, 1e-9);
    EXPECT_NEAR(p.signed_distance(L.axis_point + 100.0 * L.axis_dir), 0.0, 1e-9);
  }
  // The mirror doubles the angle: turning it by a turns the plane's normal by 2a.
  const double a = 0.03;
  const fs::Plane p0 = L.plane_at_mirror_angle(0.1), p1 = L.plane_at_mirror_angle(0.1 + a);
  EXPECT_NEAR(std::acos(std::clamp(p0.n.dot(p1.n), -1.0, 1.0)), 2 * a, 1e-9);
  // The sweep covers table x in [-150, 150]: the first and last step's planes cut the table there.
  auto table_x = [&](double step) {
    const fs::Plane p = L.plane_at_step(step);
    return (p.d - p.n.y() * 0.0) / p.n.x();  // z = 0, y = 0: n.x * x = d
  };
  EXPECT_NEAR(table_x(0), -150.0, 1e-6);
  EXPECT_NEAR(table_x(499), 150.0, 1e-6);
  EXPECT_LT(table_x(100), table_x(200));
}

TEST(LaserGeometry, ResampledSweepKeepsItsEnds) {
  auto c = fs::ScannerCalibration::bench_default(500);
  c.first_step = 10;
  c.laser.mirror_angle_at_step0 -= 10 * c.laser.rad_per_step;  // same planes, numbered from 10
  const double a0 = c.laser.mirror_angle(10), a1 = c.laser.mirror_angle(509);
  fs::sim::resample_sweep(c, 50);
  EXPECT_EQ(c.step_count, 50u);
  EXPECT_NEAR(c.laser.mirror_angle(10), a0, 1e-15);
  EXPECT_NEAR(c.laser.mirror_angle(59), a1, 1e-15);
}

TEST(RayCast, HitsNearestFaceAndTable) {
  const auto s = cube_at({10, 20, 0});
  const fs::sim::SceneRayCaster rc(s);
  fs::sim::RayHit h;
  ASSERT_TRUE(rc.cast({10, 20, 500}, {0, 0, -1}, 1e9, h));
  EXPECT_EQ(h.object, 1);
  EXPECT_NEAR(h.point.z(), 50.0, 1e-9);
  EXPECT_EQ(h.normal, Vec3(0, 0, 1));
  EXPECT_EQ(h.face, 1);  // the top face {4, 5, 6, 7}
  ASSERT_TRUE(rc.cast({100, 20, 500}, {0, 0, -1}, 1e9, h));
  EXPECT_EQ(h.object, 0);
  EXPECT_NEAR(h.point.z(), 0.0, 1e-12);
  EXPECT_FALSE(rc.cast({100, 20, 500}, {0, 0, 1}, 1e9, h));
  // From the side, through the +x face.
  ASSERT_TRUE(rc.cast({200, 20, 25}, {-1, 0, 0}, 1e9, h));
  EXPECT_EQ(h.object, 1);
  EXPECT_NEAR(h.point.x(), 35.0, 1e-9);
  EXPECT_EQ(h.normal, Vec3(1, 0, 0));
  // s_max stops short of the cube.
  EXPECT_FALSE(rc.cast({200, 20, 25}, {-1, 0, 0}, 100.0, h));
}

TEST(Visibility, PointBehindBoxIsNotLitOrNotSeen) {
  const auto s = cube_at({0, 0, 0});
  const fs::sim::SceneRayCaster rc(s);
  const Vec3 mirror = s.calibration.laser.axis_point;  // (200, 0, 500): light comes from +x
  const Vec3 camera = s.calibration.camera.center();   // (0, 0, 500)
  // Just left (-x) of the cube on the table: in the laser's shadow, but the camera sees it.
  const Vec3 shadowed(-30, 0, 0);
  EXPECT_TRUE(rc.blocked(mirror, shadowed));
  EXPECT_FALSE(rc.blocked(shadowed, camera));
  // Right (+x) of the cube: lit and seen.
  EXPECT_FALSE(rc.blocked(mirror, Vec3(40, 0, 0)));
  EXPECT_FALSE(rc.blocked(Vec3(40, 0, 0), camera));
  // A box far from the optical axis hides the table right behind it from the camera.
  const auto far = cube_at({-120, 0, 0});
  const fs::sim::SceneRayCaster rc2(far);
  const Vec3 hidden(-147, 0, 0);  // behind the box's -x edge at -145 as seen from (0, 0, 500)
  EXPECT_TRUE(rc2.blocked(hidden, camera));

  // The stripe tracer agrees: the laser plane through the shadowed point yields no table point in that row.
  fs::sim::StripeTracer tracer(s);
  std::vector<fs::sim::StripeSample> rows(s.calibration.camera.height);
  const fs::Plane through_shadow = [&] {
    // The plane containing the mirror axis (along y) and the shadowed point.
    const Vec3 n = s.calibration.laser.axis_dir.cross(shadowed - mirror).normalized();
    return fs::Plane{n, n.dot(mirror)};
  }();
  tracer.trace(through_shadow, rows);
  Vec2 px;
  ASSERT_TRUE(s.calibration.camera.project(shadowed, px));
  const auto row = static_cast<std::size_t>(std::lround(px.y()));
  EXPECT_FALSE(rows[row].valid() && rows[row].object == 0) << "shadowed table point reported";
  // Rows well away from the cube (|y| > 25 mm) do see the table on that plane.
  EXPECT_TRUE(rows[20].valid());
  EXPECT_EQ(rows[20].object, 0);

  // Camera occlusion: the plane through the hidden point yields no table point there either.
  fs::sim::StripeTracer tracer2(far);
  const Vec3 n2 = far.calibration.laser.axis_dir.cross(hidden - mirror).normalized();
  tracer2.trace(fs::Plane{n2, n2.dot(mirror)}, rows);
  ASSERT_TRUE(far.calibration.camera.project(hidden, px));
  const auto row2 = static_cast<std::size_t>(std::lround(px.y()));
  EXPECT_FALSE(rows[row2].valid() && rows[row2].object == 0 &&
               std::abs(rows[row2].point.x() - hidden.x()) < 1.0);
}

// Every valid cell is on its laser plane, projects onto its row and column, lies in its face polygon, and is
// the first surface from both the mirror and the camera (independent ray casts).
void check_grid_consistent(const fs::sim::Scene& s, const fs::sim::GroundTruthGrid& g) {
  const fs::sim::SceneRayCaster rc(s);
  const Vec3 S = s.calibration.laser.axis_point, C = s.calibration.camera.center();
  std::size_t checked = 0;
  for (std::uint32_t k = 0; k < g.steps(); ++k) {
    const fs::Plane plane = s.calibration.laser.plane_at_step(k);
    for (std::uint32_t r = 0; r < g.rows(); ++r) {
      const auto& c = g.at(k, r);
      if (!c.valid()) continue;
      ++checked;
      ASSERT_NEAR(plane.signed_distance(c.true_point), 0.0, 1e-6);
      Vec2 px;
      ASSERT_TRUE(s.calibration.camera.project(c.true_point, px));
      ASSERT_NEAR(px.y(), r, 1e-6);
      ASSERT_NEAR(px.x(), c.column, 1e-6);
      ASSERT_EQ(c.point, c.true_point);
      fs::sim::RayHit h;
      ASSERT_TRUE(rc.cast(C, (c.true_point - C).normalized(), 1e9, h));
      ASSERT_NEAR((h.point - c.true_point).norm(), 0.0, 1e-3) << "step " << k << " row " << r;
      ASSERT_TRUE(rc.cast(S, (c.true_point - S).normalized(), 1e9, h));
      ASSERT_NEAR((h.point - c.true_point).norm(), 0.0, 1e-3) << "step " << k << " row " << r;
      if (c.object > 0) {
        const auto& f =
            s.objects[static_cast<std::size_t>(c.object - 1)].faces[static_cast<std::size_t>(c.face)];
        ASSERT_NEAR(f.plane.signed_distance(c.true_point), 0.0, 1e-6);
        ASSERT_EQ(c.normal, f.plane.n);
      } else {
        ASSERT_NEAR(c.true_point.z(), 0.0, 1e-9);
      }
    }
  }
  EXPECT_GT(checked, g.steps() * g.rows() / 2);
}

TEST(GroundTruthGrid, CellsAreLitSeenAndOnTheirPlaneWithALowMirror) {
  auto s = scene_file("default", 40);
  lower_the_mirror(s);
  const auto g = fs::sim::make_ground_truth_grid(s);
  check_grid_consistent(s, g);
  std::size_t multi = 0;
  fs::sim::StripeTracer t(s);
  std::vector<fs::sim::StripeSample> rows(s.calibration.camera.height);
  for (std::uint32_t k = 0; k < 40; ++k) {
    t.trace(s.calibration.laser.plane_at_step(k), rows);
    for (const auto& r : rows) multi += r.candidates > 1 ? 1 : 0;
  }
  RecordProperty("rows_with_several_candidates", std::to_string(multi));
}

TEST(GroundTruthGrid, CellsAreLitSeenAndOnTheirPlane) {
  const auto s = scene_file("default", 60);
  const auto g = fs::sim::make_ground_truth_grid(s);
  EXPECT_EQ(g.steps(), 60u);
  EXPECT_EQ(g.rows(), 1024u);
  check_grid_consistent(s, g);
  // Every object shows up, with several faces each.
  for (std::int32_t o = 1; o <= static_cast<std::int32_t>(s.objects.size()); ++o)
    EXPECT_GT(g.count_object(o), 100u);
  EXPECT_GT(g.count_object(0), g.valid_count() / 2);
}

// drop_points loses about the share asked of the measured points (NaN, label -1), the same ones for one seed,
// and leaves the unmeasured cells alone.
TEST(GroundTruthGrid, DropPointsLosesTheShareAskedTheSameForOneSeed) {
  struct Cloud {
    std::vector<Eigen::Vector3f> points;
    std::vector<std::int32_t> labels;
  };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  Cloud a;
  for (int i = 0; i < 100000; ++i) {
    a.points.emplace_back(i % 10 == 0 ? Eigen::Vector3f(nan, nan, nan) : Eigen::Vector3f(1.0f, 2.0f, 3.0f));
    a.labels.push_back(i % 10 == 0 ? -1 : 7);
  }
  Cloud b = a, c = a;
  fs::sim::drop_points(a, 0.05, 11);
  fs::sim::drop_points(b, 0.05, 11);
  fs::sim::drop_points(c, 0.05, 12);
  std::size_t lost = 0, differ = 0;
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    const bool measured = i % 10 != 0;
    const bool gone = std::isnan(a.points[i].z());
    ASSERT_EQ(gone, std::isnan(b.points[i].z()));
    ASSERT_EQ(a.labels[i], gone ? -1 : 7);
    if (!measured) {
      ASSERT_TRUE(gone);
      continue;
    }
    lost += gone ? 1 : 0;
    differ += gone != std::isnan(c.points[i].z()) ? 1 : 0;
  }
  EXPECT_NEAR(static_cast<double>(lost) / 90000.0, 0.05, 0.005);
  EXPECT_GT(differ, 1000u);  // another seed, other points
}

// The oblique rig (camera in front, tilted; laser from behind): a step's stripe is a line of constant y on
// the table, the sweep runs from y = -110 to 110 mm, the image rows run along x, and the scene's cells are
// lit, seen and on their planes as with the bench rig.
TEST(ObliqueRig, SweepsTheTableAlongYWithImageRowsAlongX) {
  fs::sim::Scene s;
  s.source = "empty table";
  s.calibration = fs::sim::oblique_rig(240);
  const auto g = fs::sim::make_ground_truth_grid(s);
  ASSERT_EQ(g.steps(), 240u);
  ASSERT_EQ(g.rows(), 320u);
  double x_min = 1e9, x_max = -1e9;
  for (std::uint32_t k = 0; k < g.steps(); ++k) {
    double y_min = 1e9, y_max = -1e9, prev_x = -1e9;
    for (std::uint32_t r = 0; r < g.rows(); ++r) {
      const auto& c = g.at(k, r);
      if (!c.valid()) continue;
      y_min = std::min(y_min, c.true_point.y()), y_max = std::max(y_max, c.true_point.y());
      ASSERT_GT(c.true_point.x(), prev_x) << "step " << k << " row " << r;  // rows along +x
      prev_x = c.true_point.x();
      x_min = std::min(x_min, prev_x), x_max = std::max(x_max, prev_x);
    }
    ASSERT_LT(y_max - y_min, 1e-6) << "step " << k;
    if (k == 0) {
      EXPECT_NEAR(y_min, -110.0, 1e-6);
    }
    if (k + 1 == g.steps()) {
      EXPECT_NEAR(y_min, 110.0, 1e-6);
    }
  }
  EXPECT_LT(x_min, -130.0);
  EXPECT_GT(x_max, 130.0);
  EXPECT_EQ(g.valid_count(), static_cast<std::size_t>(g.steps()) * g.rows());  // the whole table is seen
}

TEST(ObliqueRig, CellsAreLitSeenAndOnTheirPlane) {
  auto s = scene_file("default");
  s.calibration = fs::sim::oblique_rig(60);
  const auto g = fs::sim::make_ground_truth_grid(s);
  check_grid_consistent(s, g);
  for (std::int32_t o = 1; o <= static_cast<std::int32_t>(s.objects.size()); ++o)
    EXPECT_GT(g.count_object(o), 50u) << s.objects[static_cast<std::size_t>(o - 1)].name;
  // Camera and laser on opposite sides: no measured face turns away from either of them.
  for (const auto& c : g.cells()) {
    if (c.object <= 0) continue;
    EXPECT_GT(c.normal.dot(s.calibration.camera.center() - c.true_point), 0.0);
    EXPECT_GT(c.normal.dot(s.calibration.laser.axis_point - c.true_point), 0.0);
  }
}

// Completeness: scan image rows with camera rays; wherever the seen surface crosses the laser plane between
// two neighbouring columns and that surface is lit, the grid must have the stripe point in between.
class GroundTruthCompleteness : public ::testing::TestWithParam<bool> {};

TEST_P(GroundTruthCompleteness, FindsEveryLitAndSeenCrossing) {
  auto s = scene_file("cube-occludes-pyramid", 40);
  if (GetParam()) lower_the_mirror(s);
  const auto g = fs::sim::make_ground_truth_grid(s);
  const fs::sim::SceneRayCaster rc(s);
  const auto& cam = s.calibration.camera;
  const Vec3 S = s.calibration.laser.axis_point;
  int crossings = 0;
  for (std::uint32_t k = 0; k < g.steps(); k += 3) {
    const fs::Plane plane = s.calibration.laser.plane_at_step(k);
    for (std::uint32_t r = 0; r < cam.height; r += 37) {
      double prev_d = 0.0;
      fs::sim::RayHit prev{};
      bool have_prev = false;
      for (std::uint32_t u = 0; u < cam.width; ++u) {
        fs::sim::RayHit h;
        const bool hit = rc.cast(cam.center(), cam.ray_world(Vec2(u, r)), 1e9, h);
        const double d = hit ? plane.signed_distance(h.point) : 0.0;
        if (hit && have_prev && (d > 0) != (prev_d > 0) && h.object == prev.object && h.face == prev.face &&
            !rc.blocked(S, h.point) && h.normal.dot(S - h.point) > 0) {
          ++crossings;
          const auto& c = g.at(k, r);
          ASSERT_TRUE(c.valid()) << "step " << k << " row " << r << " u " << u;
          // The nearest-to-camera point wins; here the crossing must be the one found or a nearer one.
          if (c.object == h.object && c.face == h.face) {
            EXPECT_NEAR(c.column, u - 0.5, 0.5 + 1e-6);
          }
        }
        prev_d = d;
        prev = h;
        have_prev = hit;
      }
    }
  }
  EXPECT_GT(crossings, 200);
}
INSTANTIATE_TEST_SUITE_P(BenchAndLowMirror, GroundTruthCompleteness, ::testing::Bool());

TEST(GroundTruthGrid, ShadowAndOcclusionRemoveCells) {
  // The cube nearer the laser shadows part of the pyramid: fewer pyramid cells than with the pyramid alone.
  const auto both = scene_file("cube-occludes-pyramid", 80);
  fs::sim::Scene alone = both;
  alone.objects.erase(alone.objects.begin());  // the cube is object 0 of the file
  const auto g_both = fs::sim::make_ground_truth_grid(both);
  const auto g_alone = fs::sim::make_ground_truth_grid(alone);
  const std::size_t pyr_both = g_both.count_object(2), pyr_alone = g_alone.count_object(1);
  EXPECT_GT(pyr_both, 1000u);
  EXPECT_LT(static_cast<double>(pyr_both), 0.97 * static_cast<double>(pyr_alone));
}

TEST(GroundTruthGrid, DepthNoiseMovesPointsAlongTheViewingRay) {
  const auto s = scene_file("cube", 30);
  const auto exact = fs::sim::make_ground_truth_grid(s);
  const auto noisy = fs::sim::make_ground_truth_grid(s, {.depth_noise_mm = 0.5, .seed = 9});
  const auto again = fs::sim::make_ground_truth_grid(s, {.depth_noise_mm = 0.5, .seed = 9});
  const Vec3 C = s.calibration.camera.center();
  double sum = 0.0, sum2 = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < noisy.cells().size(); ++i) {
    const auto& a = noisy.cells()[i];
    ASSERT_EQ(a.valid(), exact.cells()[i].valid());
    if (!a.valid()) continue;
    ASSERT_EQ(a.true_point, exact.cells()[i].true_point);
    ASSERT_EQ(a.point, again.cells()[i].point);  // deterministic per seed
    const Vec3 ray = (a.true_point - C).normalized();
    const Vec3 d = a.point - a.true_point;
    ASSERT_NEAR((d - ray * d.dot(ray)).norm(), 0.0, 1e-9);  // along the ray
    sum += d.dot(ray);
    sum2 += d.dot(ray) * d.dot(ray);
    ++n;
  }
  ASSERT_GT(n, 1000u);
  EXPECT_NEAR(sum / n, 0.0, 0.05);
  EXPECT_NEAR(std::sqrt(sum2 / n), 0.5, 0.05);
}

TEST(GroundTruthGrid, ExportsAnOrganizedCloud) {
  struct Cloud {  // the shape of fs::host::OrganizedCloud
    std::uint32_t width = 0, height = 0;
    std::vector<Eigen::Vector3f> points;
    std::vector<std::int32_t> labels;
    Eigen::Vector3d viewpoint;
    std::optional<fs::ScannerCalibration> scanner;
    void reset(std::uint32_t w, std::uint32_t h, bool with_labels) {
      width = w;
      height = h;
      const float nan = std::nanf("");
      points.assign(std::size_t(w) * h, Eigen::Vector3f(nan, nan, nan));
      labels.assign(with_labels ? std::size_t(w) * h : 0, -1);
    }
  } cloud;
  const auto s = scene_file("cube", 20);
  const auto g = fs::sim::make_ground_truth_grid(s);
  g.export_to(cloud);
  EXPECT_EQ(cloud.width, 20u);
  EXPECT_EQ(cloud.height, 1024u);
  const auto& c = g.at(7, 512);
  ASSERT_TRUE(c.valid());
  EXPECT_TRUE(cloud.points[512 * 20 + 7].isApprox(c.point.cast<float>()));
  EXPECT_EQ(cloud.labels[512 * 20 + 7], c.label());
  ASSERT_TRUE(cloud.scanner.has_value());
  EXPECT_EQ(cloud.scanner->step_count, 20u);
  EXPECT_EQ(cloud.viewpoint, s.calibration.camera.center());
}

}  // namespace
