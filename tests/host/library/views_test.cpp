// partial_view: the PFRG an ideal sensor sees of a model.
#include <gtest/gtest.h>

#include "host/library/polycubes.hpp"
#include "host/library/views.hpp"

namespace {

using namespace fs::host;
using fs::Mat3;
using fs::Vec3;

TEST(Views, CubeFromAboveSeesTheTopFace) {
  const Model cube = polycube_model({{0, 0, 0}}, 10, "cube");
  const Pfrg g = partial_view(cube, Mat3::Identity(), Vec3(0, 0, -1));
  ASSERT_EQ(g.nodes.size(), 2u);
  EXPECT_FALSE(g.nodes[0].supernode);
  EXPECT_TRUE(g.nodes[0].normal.isApprox(Vec3::UnitZ()));
  EXPECT_NEAR(g.nodes[0].area, 100, 1e-12);
  EXPECT_TRUE(g.nodes[1].supernode);
  EXPECT_EQ(g.nodes[1].id, 6);
  ASSERT_EQ(g.arcs.size(), 1u);
  EXPECT_NEAR(g.arcs[0].border, 40, 1e-12);  // the whole top perimeter borders invisible faces
  EXPECT_TRUE(g.has_observer);
  EXPECT_TRUE(g.observer.isApprox(Vec3::UnitZ()));
}

TEST(Views, CornerViewShowsThreeFaces) {
  const Model cube = polycube_model({{0, 0, 0}}, 10, "cube");
  ViewOptions o;
  o.translation = Vec3(100, 0, 0);
  const Pfrg g = partial_view(cube, Mat3::Identity(), Vec3(-1, -1, -1), o);
  ASSERT_EQ(g.nodes.size(), 4u);
  int super_arcs = 0;
  double inner = 0;
  for (const auto& a : g.arcs) {
    if (a.b == 6) {
      ++super_arcs;
      EXPECT_NEAR(a.border, 20, 1e-12);
    } else
      inner += a.border;
  }
  EXPECT_EQ(super_arcs, 3);
  EXPECT_NEAR(inner, 30, 1e-12);
  for (const auto& n : g.nodes)
    if (!n.supernode) {
      EXPECT_GT(n.normal.dot(Vec3(1, 1, 1)), 0);
      EXPECT_NEAR(n.normal.dot(n.centroid), n.offset, 1e-9);
      EXPECT_GT(n.centroid.x(), 99);
    }
}

TEST(Views, RotationRotatesNormalsAndChangesVisibility) {
  const Model rod = polycube_model({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}, 10, "rod");
  // Rotate the rod's long axis (x) onto the viewing axis z: from above only a 10x10 end is visible.
  const Mat3 R = Eigen::AngleAxisd(-M_PI / 2, Vec3::UnitY()).toRotationMatrix();
  const auto vis = visible_faces(rod, R, Vec3(0, 0, -1));
  ASSERT_EQ(vis.size(), 1u);
  EXPECT_NEAR(rod.faces[static_cast<std::size_t>(vis[0])].area, 100, 1e-9);
  EXPECT_TRUE((R * rod.faces[static_cast<std::size_t>(vis[0])].normal).isApprox(Vec3::UnitZ()));
  ViewOptions none;
  none.supernode = false;
  const Pfrg g = partial_view(rod, R, Vec3(0, 0, -1), none);
  EXPECT_EQ(g.nodes.size(), 1u);
  EXPECT_TRUE(g.arcs.empty());
}

TEST(Views, NonConvexModelKeepsConcaveArcsBetweenVisibleFaces) {
  const Model L = polycube_model({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, 10, "L");
  const Pfrg g = partial_view(L, Mat3::Identity(), Vec3(-1, -1, -1));
  // Visible: +x faces (2), +y faces (2), top: 5 faces; the concave edge joins a +x and a +y face.
  std::size_t faces = 0;
  for (const auto& n : g.nodes) faces += !n.supernode;
  EXPECT_EQ(faces, 5u);
  bool concave = false;
  for (const auto& a : g.arcs) {
    if (a.a >= 8 || a.b >= 8) continue;
    const Vec3 na = L.faces[static_cast<std::size_t>(a.a)].normal,
               nb = L.faces[static_cast<std::size_t>(a.b)].normal;
    const Vec3 d =
        L.faces[static_cast<std::size_t>(a.b)].centroid - L.faces[static_cast<std::size_t>(a.a)].centroid;
    concave = concave || (na.dot(d) > 1e-9 && nb.dot(-d) > 1e-9);
  }
  EXPECT_TRUE(concave);
}

}  // namespace
