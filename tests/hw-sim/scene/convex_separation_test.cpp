// The exact convex-solid overlap test of cluttered scenes (hw-sim/scene/convex_separation.hpp): gaps,
// touching, penetration depth, the edge-edge case that face normals and vertex tests miss, translation.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include <Eigen/Geometry>

#include "hw-sim/scene/convex_separation.hpp"
#include "hw-sim/scene/scene.hpp"

namespace {

using fs::Mat3;
using fs::Vec3;
using fs::sim::ConvexShape;

fs::Mesh cube(double half) {
  fs::Mesh m;
  m.name = "cube";
  for (int i = 0; i < 8; ++i)
    m.vertices.emplace_back(i & 1 ? half : -half, i & 2 ? half : -half, i & 4 ? half : -half);
  m.faces = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  return m;
}

Mat3 rot(const Vec3& axis, double deg) {
  return Eigen::AngleAxisd(deg * std::numbers::pi / 180.0, axis.normalized()).toRotationMatrix();
}

// Independent: a vertex of `a` strictly behind every face plane of `b`.
bool vertex_inside(const fs::sim::SceneObject& a, const fs::sim::SceneObject& b) {
  for (const auto& fa : a.faces)
    for (const auto& x : fa.polygon) {
      bool inside = true;
      for (const auto& fb : b.faces) inside = inside && fb.plane.signed_distance(x) < -1e-9;
      if (inside) return true;
    }
  return false;
}

TEST(ConvexSeparation, CubesApartTouchingAndOverlapping) {
  const auto a = ConvexShape::of(cube(1), Mat3::Identity(), Vec3::Zero());
  EXPECT_NEAR(separation(a, ConvexShape::of(cube(1), Mat3::Identity(), Vec3(3, 0, 0))), 1.0, 1e-12);
  EXPECT_NEAR(separation(a, ConvexShape::of(cube(1), Mat3::Identity(), Vec3(2, 0.5, 0))), 0.0, 1e-12);
  EXPECT_NEAR(separation(a, ConvexShape::of(cube(1), Mat3::Identity(), Vec3(1.5, 0.2, 0.1))), -0.5, 1e-12);
  // A cube yawed 45 degrees beside an upright one: its edge, not a face, comes closest.
  EXPECT_NEAR(
      separation(a, ConvexShape::of(cube(1), rot(Vec3::UnitZ(), 45), Vec3(1 + std::sqrt(2.0) + 0.3, 0, 0))),
      0.3, 1e-12);
  EXPECT_EQ(a.normals.size(), 3u);  // opposite faces give one axis
  EXPECT_EQ(a.edges.size(), 3u);
}

TEST(ConvexSeparation, CrossedEdgesNeedEdgeAxes) {
  // A's lowest edge runs along y, B's highest along x; they cross `gap` apart in z.
  const double r2 = std::sqrt(2.0);
  for (const double gap : {0.1, 0.0, -0.1}) {
    SCOPED_TRACE(gap);
    fs::sim::Scene scene;
    fs::sim::add_object(scene, cube(1), rot(Vec3::UnitY(), 45), Vec3(0, 0, 2 * r2 + gap));
    fs::sim::add_object(scene, cube(1), rot(Vec3::UnitX(), 45), Vec3::Zero());
    const double s = separation(ConvexShape::of(scene.objects[0]), ConvexShape::of(scene.objects[1]));
    if (gap >= 0) {
      EXPECT_NEAR(s, gap, 1e-9);  // the axis z = cross(y, x)
    } else {
      EXPECT_LT(s, 0.0);  // interpenetrating, though no vertex is inside the other solid
      EXPECT_GE(s, gap - 1e-9);
      EXPECT_FALSE(vertex_inside(scene.objects[0], scene.objects[1]));
      EXPECT_FALSE(vertex_inside(scene.objects[1], scene.objects[0]));
    }
  }
}

TEST(ConvexSeparation, PairSeparationFollowsATranslation) {
  fs::Mesh wedge;
  wedge.name = "wedge";
  wedge.vertices = {{0, 0, 0}, {20, 0, 0}, {0, 12, 0}, {0, 0, 9}, {20, 0, 9}, {0, 12, 9}};
  wedge.faces = {{0, 2, 1}, {3, 4, 5}, {0, 1, 4, 3}, {1, 2, 5, 4}, {2, 0, 3, 5}};
  const Mat3 ra = rot(Vec3(1, 2, 3), 37), rb = rot(Vec3(-2, 1, 0.5), 71);
  const auto a = ConvexShape::of(wedge, ra, Vec3::Zero());
  const auto b = ConvexShape::of(cube(8), rb, Vec3(5, 3, -2));
  const fs::sim::PairSeparation pair(a, b);
  for (const Vec3& t :
       {Vec3(0, 0, 0), Vec3(30, 0, 0), Vec3(-4, 11, 2), Vec3(10, -20, 15), Vec3(-25, 3, -9)}) {
    const double s = separation(ConvexShape::of(wedge, ra, t), b);
    EXPECT_NEAR(pair.at(t), s, 1e-9);
    EXPECT_NEAR(separation(b, ConvexShape::of(wedge, ra, t)), s, 1e-9);  // symmetric
    EXPECT_TRUE(pair.at_least(t, s - 1e-6));
    EXPECT_FALSE(pair.at_least(t, s + 1e-6));
  }
}

}  // namespace
