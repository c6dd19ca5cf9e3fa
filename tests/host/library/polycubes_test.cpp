// Polycubes (thesis ch. 4.1.3): counts up to rotation and translation, surfaces and PFRGs.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "common/error.hpp"
#include "host/library/polycubes.hpp"

namespace {

using namespace fs::host;

TEST(Polycubes, CubeRotationGroup) {
  const auto& rots = cube_rotations();
  std::set<std::vector<double>> distinct;
  for (const auto& R : rots) {
    EXPECT_NEAR(R.determinant(), 1.0, 0.0);
    distinct.insert(std::vector<double>(R.data(), R.data() + 9));
  }
  EXPECT_EQ(distinct.size(), 24u);
}

TEST(Polycubes, CountsUpToRotationAndTranslation) {
  const auto all = enumerate_polycubes(6);
  ASSERT_EQ(all.size(), 6u);
  const std::size_t expected[] = {1, 1, 2, 8, 29, 166};
  for (std::size_t v = 0; v < 6; ++v) EXPECT_EQ(all[v].size(), expected[v]) << "volume " << v + 1;
  for (std::size_t v = 0; v < 6; ++v)
    for (const auto& p : all[v]) {
      EXPECT_EQ(p.size(), v + 1);
      EXPECT_EQ(canonical_polycube(p), p);
    }
  EXPECT_THROW(enumerate_polycubes(0), fs::Error);
  EXPECT_THROW(enumerate_polycubes(11), fs::Error);
}

TEST(Polycubes, MirrorImagesAreDistinctRotationsAreNot) {
  // The two chiral tetracubes: mirror images of each other, both present.
  const Polycube a{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {1, 1, 1}};
  const Polycube b{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {1, 1, -1}};
  EXPECT_NE(canonical_polycube(a), canonical_polycube(b));
  const auto all = enumerate_polycubes(4);
  std::set<Polycube> four(all[3].begin(), all[3].end());
  EXPECT_TRUE(four.count(canonical_polycube(a)));
  EXPECT_TRUE(four.count(canonical_polycube(b)));
  // A rotated and shifted copy is the same object.
  Polycube moved;
  for (const auto& c : a) moved.push_back({-c[1] + 5, c[0] - 2, c[2] + 7});
  EXPECT_EQ(canonical_polycube(moved), canonical_polycube(a));
}

TEST(Polycubes, ModelsAreConsistentSurfaces) {
  const auto all = enumerate_polycubes(6);
  const double edge = 10;
  std::size_t models = 0;
  for (std::size_t v = 0; v < all.size(); ++v)
    for (std::size_t i = 0; i < all[v].size(); ++i) {
      const Polycube& p = all[v][i];
      const std::string name = polycube_name(static_cast<int>(v + 1), i + 1);
      SCOPED_TRACE(name);
      const Model m = polycube_model(p, edge, name);
      ++models;
      const std::set<Cell> occ(p.begin(), p.end());
      int exposed = 0;
      for (const auto& c : p)
        for (int a = 0; a < 3; ++a)
          for (int s : {-1, 1}) {
            Cell n = c;
            n[static_cast<std::size_t>(a)] += s;
            exposed += occ.count(n) == 0;
          }
      EXPECT_EQ(m.name, name);
      EXPECT_FALSE(m.open);
      EXPECT_NEAR(m.total_area, exposed * edge * edge, 1e-9);
      EXPECT_NEAR(m.volume, static_cast<double>(v + 1) * edge * edge * edge, 1e-6);
      EXPECT_LE(m.face_count(), static_cast<std::size_t>(exposed));
      EXPECT_GE(m.face_count(), 6u);
      // Symmetry group from faces = rotations of the cell set.
      EXPECT_EQ(static_cast<int>(m.symmetry_order()), polycube_symmetry_order(p));
      // Face normals are axis directions, areas whole squares, arcs carry each face's perimeter.
      std::vector<double> border(m.face_count(), 0.0);
      for (const auto& a : m.graph.arcs) {
        EXPECT_GT(a.border, 0.0);
        EXPECT_NE(
            m.faces[static_cast<std::size_t>(a.a)].normal.dot(m.faces[static_cast<std::size_t>(a.b)].normal),
            1.0);
        border[static_cast<std::size_t>(a.a)] += a.border;
        border[static_cast<std::size_t>(a.b)] += a.border;
      }
      for (std::size_t f = 0; f < m.face_count(); ++f) {
        EXPECT_NEAR(m.faces[f].normal.cwiseAbs().maxCoeff(), 1.0, 1e-12);
        EXPECT_NEAR(border[f], m.faces[f].perimeter, 1e-9);
        const double squares = m.faces[f].area / (edge * edge);
        EXPECT_NEAR(squares, std::round(squares), 1e-9);
      }
    }
  EXPECT_EQ(models, 207u);
}

TEST(Polycubes, KnownShapes) {
  // Volume 1: a cube; volume 2: a 1x1x2 box; the straight tricube 1x1x3; the 2x2 square tetracube.
  const Model cube = polycube_model({{0, 0, 0}}, 1, "c");
  EXPECT_EQ(cube.face_count(), 6u);
  EXPECT_EQ(cube.symmetry_order(), 24u);
  const Model rod = polycube_model({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}, 1, "rod");
  EXPECT_EQ(rod.face_count(), 6u);
  EXPECT_EQ(rod.arc_count(), 12u);
  EXPECT_NEAR(rod.total_border(), 4 * (3 + 1 + 1), 1e-12);
  EXPECT_EQ(rod.symmetry_order(), 8u);
  const Model sq = polycube_model({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}}, 1, "sq");
  EXPECT_EQ(sq.face_count(), 6u);
  EXPECT_EQ(sq.symmetry_order(), 8u);
  // T tetracube: 10 faces.
  const Model t = polycube_model({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {1, 1, 0}}, 1, "T");
  EXPECT_EQ(t.face_count(), 10u);
  EXPECT_EQ(t.symmetry_order(), 2u);
  EXPECT_EQ(polycube_name(5, 7), "polycube-5-007");
}

}  // namespace

namespace {

TEST(Polycubes, CountsForVolumesSevenAndEight) {
  const auto all = fs::host::enumerate_polycubes(8);
  EXPECT_EQ(all[6].size(), 1023u);
  EXPECT_EQ(all[7].size(), 6922u);
}

}  // namespace
