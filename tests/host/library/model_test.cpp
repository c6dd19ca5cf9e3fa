// build_model on meshes made in memory and in files: triangulated cubes, wrong winding, open and
// non-manifold meshes, bad input.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "common/error.hpp"
#include "common/mesh.hpp"
#include "host/library/model.hpp"
#include "host/library/polycubes.hpp"

namespace {

using fs::Mesh;
using fs::Vec3;
using fs::host::build_model;
using fs::host::BuildOptions;
using fs::host::Model;

// An axis-aligned box [0,a]x[0,b]x[0,c] as 12 outward triangles (each quad split).
Mesh triangulated_box(double a, double b, double c) {
  Mesh m;
  m.name = "box";
  for (int i = 0; i < 8; ++i) m.vertices.emplace_back(i & 1 ? a : 0, i & 2 ? b : 0, i & 4 ? c : 0);
  const std::uint32_t q[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                 {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : q) {
    m.faces.push_back({f[0], f[1], f[2]});
    m.faces.push_back({f[0], f[2], f[3]});
  }
  return m;
}

void expect_box(const Model& m, double a, double b, double c, double rel = 1e-12) {
  ASSERT_EQ(m.face_count(), 6u);
  EXPECT_EQ(m.arc_count(), 12u);
  EXPECT_NEAR(m.total_area, 2 * (a * b + b * c + a * c), rel * m.total_area);
  EXPECT_NEAR(m.volume, a * b * c, rel * m.volume);
  EXPECT_NEAR(m.total_border(), 4 * (a + b + c), rel * m.total_border());
  EXPECT_LT((m.center - Vec3(a / 2, b / 2, c / 2)).norm(), rel * m.bounding_radius);
  for (const auto& f : m.faces) {
    EXPECT_GT(f.normal.dot(f.centroid - m.center), 0.0) << "inward normal";
    ASSERT_EQ(f.loops.size(), 1u);
    EXPECT_EQ(f.loops[0].size(), 4u);  // diagonal of the triangulation is gone
  }
}

TEST(BuildModel, TriangulatedCubeGivesSixFaces) {
  const Model m = build_model(triangulated_box(10, 10, 10));
  expect_box(m, 10, 10, 10);
  EXPECT_EQ(m.symmetry_order(), 24u);
}

TEST(BuildModel, BoxSymmetryOrders) {
  EXPECT_EQ(build_model(triangulated_box(10, 20, 30)).symmetry_order(), 4u);
  EXPECT_EQ(build_model(triangulated_box(10, 10, 30)).symmetry_order(), 8u);
}

// One face per orbit of the rotation group: the cube's six faces are one orbit, a square prism's ends and its
// sides two, a box of three edge lengths has three pairs of opposite faces.
TEST(BuildModel, FaceOrbitRepresentativesOnePerOrbit) {
  auto orbits = [](const Model& m) {
    const std::vector<int> rep = fs::host::face_orbit_representatives(m);
    EXPECT_EQ(rep.size(), m.face_count());
    int n = 0;
    for (std::size_t f = 0; f < rep.size(); ++f) {
      EXPECT_LE(rep[f], static_cast<int>(f));
      EXPECT_EQ(rep[static_cast<std::size_t>(rep[f])], rep[f]);
      // A face and its representative are alike (area).
      EXPECT_NEAR(m.faces[f].area, m.faces[static_cast<std::size_t>(rep[f])].area, 1e-9 * m.faces[f].area);
      n += rep[f] == static_cast<int>(f);
    }
    return n;
  };
  EXPECT_EQ(orbits(build_model(triangulated_box(10, 10, 10))), 1);
  EXPECT_EQ(orbits(build_model(triangulated_box(10, 10, 30))), 2);
  EXPECT_EQ(orbits(build_model(triangulated_box(10, 20, 30))), 3);
  Model no_symmetry = build_model(triangulated_box(10, 20, 30));
  no_symmetry.symmetries.resize(1);
  EXPECT_EQ(orbits(no_symmetry), 6);
}

TEST(BuildModel, StlFileCubeGivesSixFaces) {
  const Mesh box = triangulated_box(25, 25, 25);
  const auto path = std::filesystem::temp_directory_path() / "fs_library_test_cube.stl";
  {
    std::ofstream out(path);
    out << "solid cube\n";
    for (const auto& f : box.faces) {
      out << " facet normal 0 0 0\n  outer loop\n";
      for (auto i : f)
        out << "   vertex " << box.vertices[i].x() << ' ' << box.vertices[i].y() << ' ' << box.vertices[i].z()
            << '\n';
      out << "  endloop\n endfacet\n";
    }
    out << "endsolid cube\n";
  }
  const Model m = build_model(fs::read_mesh(path));
  std::filesystem::remove(path);
  expect_box(m, 25, 25, 25);
}

TEST(BuildModel, ReversedAndMixedWindingGiveOutwardNormals) {
  Mesh m = triangulated_box(10, 20, 30);
  for (auto& f : m.faces) std::reverse(f.begin(), f.end());
  expect_box(build_model(m), 10, 20, 30);
  Mesh mixed = triangulated_box(10, 20, 30);
  for (std::size_t i = 0; i < mixed.faces.size(); i += 3)
    std::reverse(mixed.faces[i].begin(), mixed.faces[i].end());
  expect_box(build_model(mixed), 10, 20, 30);
}

TEST(BuildModel, ScaleAndSeparateVerticesPerTriangle) {
  // A triangle soup (no shared vertex indices) with coordinates off by less than the weld tolerance.
  const Mesh box = triangulated_box(1, 1, 1);
  Mesh soup;
  soup.name = "soup";
  for (const auto& f : box.faces) {
    std::vector<std::uint32_t> idx;
    for (auto i : f) {
      idx.push_back(static_cast<std::uint32_t>(soup.vertices.size()));
      soup.vertices.push_back(box.vertices[i] +
                              Vec3::Constant(1e-9 * static_cast<double>(soup.vertices.size() % 3)));
    }
    soup.faces.push_back(idx);
  }
  BuildOptions o;
  o.scale = 40;
  expect_box(build_model(soup, o), 40, 40, 40, 1e-8);
}

TEST(BuildModel, OpenMeshRejectedOrFlagged) {
  Mesh m = triangulated_box(10, 10, 10);
  m.faces.pop_back();
  m.faces.pop_back();
  try {
    build_model(m);
    FAIL() << "open mesh accepted";
  } catch (const fs::Error& e) {
    EXPECT_NE(std::string(e.what()).find("box: open mesh"), std::string::npos) << e.what();
  }
  BuildOptions o;
  o.allow_open = true;
  const Model open = build_model(m, o);
  EXPECT_TRUE(open.open);
  EXPECT_EQ(open.face_count(), 5u);
  EXPECT_EQ(open.arc_count(), 8u);
  for (const auto& f : open.faces) EXPECT_GT(f.normal.dot(f.centroid - Vec3(5, 5, 5)), 0.0);
}

TEST(BuildModel, NonManifoldEdgeRejectedUnlessItIsASolidPinch) {
  // Three boxes' worth of facets on one edge: a fin (a lone triangle) glued to a closed box's edge.
  Mesh m = triangulated_box(10, 10, 10);
  m.vertices.emplace_back(-5, -5, 5);
  m.faces.push_back({0, 1, static_cast<std::uint32_t>(m.vertices.size() - 1)});
  EXPECT_THROW(build_model(m), fs::Error);
  // Two cubes touching along one edge only: a closed, consistently wound solid; faces pair radially.
  const fs::host::Polycube pinch{{0, 0, 0}, {1, 1, 0}};
  const Model two = build_model(fs::host::polycube_mesh(pinch, 10, "pinch"));
  EXPECT_EQ(two.face_count(), 12u);
  EXPECT_EQ(two.arc_count(), 24u);  // each cube keeps its own 12 edges
  EXPECT_NEAR(two.volume, 2000, 1e-9);
}

TEST(BuildModel, BadInputNamesTheMesh) {
  Mesh empty;
  empty.name = "empty";
  EXPECT_THROW(build_model(empty), fs::Error);
  Mesh bad = triangulated_box(1, 1, 1);
  bad.faces[3][1] = 99;
  try {
    build_model(bad);
    FAIL();
  } catch (const fs::Error& e) {
    EXPECT_NE(std::string(e.what()).find("box: face 3: vertex index 99 out of range"), std::string::npos)
        << e.what();
  }
  Mesh flat;
  flat.name = "flat";
  flat.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3(3, 0, 0)};
  flat.faces = {{0, 1, 2}, {1, 2, 3}, {0, 2, 3}, {0, 1, 3}};
  EXPECT_THROW(build_model(flat), fs::Error);
  Mesh nan = triangulated_box(1, 1, 1);
  nan.vertices[0].x() = std::nan("");
  EXPECT_THROW(build_model(nan), fs::Error);
  BuildOptions neg;
  neg.scale = -1;
  EXPECT_THROW(build_model(triangulated_box(1, 1, 1), neg), fs::Error);
}

TEST(BuildModel, LShapeIsNonConvexWithHoleFreeFaces) {
  // An L-shaped prism: 8 faces, the concave edge joins two faces whose normals point away from each other.
  const Model m = build_model(fs::host::polycube_mesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, 10, "L"));
  EXPECT_EQ(m.face_count(), 8u);
  EXPECT_EQ(m.arc_count(), 18u);
  EXPECT_NEAR(m.total_area, 14 * 100.0, 1e-9);
  EXPECT_EQ(m.symmetry_order(), 2u);
}

TEST(BuildModel, FaceWithHole) {
  // A ring of 8 cubes around an empty centre: top and bottom faces are squares with a square hole.
  fs::host::Polycube ring;
  for (int x = 0; x < 3; ++x)
    for (int y = 0; y < 3; ++y)
      if (x != 1 || y != 1) ring.push_back({x, y, 0});
  const Model m = build_model(fs::host::polycube_mesh(ring, 1, "ring"));
  EXPECT_EQ(m.face_count(), 10u);  // top, bottom, 4 outer sides, 4 inner sides
  std::size_t holed = 0;
  for (const auto& f : m.faces)
    if (f.loops.size() == 2) {
      ++holed;
      EXPECT_NEAR(f.area, 8.0, 1e-12);
      EXPECT_NEAR(f.perimeter, 16.0, 1e-12);
    }
  EXPECT_EQ(holed, 2u);
  EXPECT_NEAR(m.volume, 8.0, 1e-12);
  EXPECT_EQ(m.symmetry_order(), 8u);
}

}  // namespace
