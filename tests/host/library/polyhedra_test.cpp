// All 120 solids of the public polyhedra set build into PFRGs matching index.csv (F, E, edge length, face
// sides), with outward normals, and known rotation group orders.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "common/mesh.hpp"
#include "host/library/model.hpp"
#include "support/test_paths.hpp"

namespace {

using fs::host::Model;

struct Row {
  std::string name;
  int V = 0, E = 0, F = 0;
  std::map<int, int> sides;  // sides -> count
  double edge = 0;
};

std::vector<Row> read_index() {
  const auto path = fs::test::shared_data() / "polyhedra/polyhedra-viewer/index.csv";
  std::ifstream in(path);
  EXPECT_TRUE(in) << path;
  std::vector<Row> rows;
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::vector<std::string> col;
    std::stringstream ss(line);
    std::string c;
    while (std::getline(ss, c, ',')) col.push_back(c);
    if (col.size() < 8) continue;
    Row r;
    r.name = col[2];
    r.V = std::stoi(col[3]);
    r.E = std::stoi(col[4]);
    r.F = std::stoi(col[5]);
    std::stringstream fs(col[6]);
    std::string tok;
    while (fs >> tok) {
      const auto x = tok.find('x');
      r.sides[std::stoi(tok.substr(x + 1))] += std::stoi(tok.substr(0, x));
    }
    r.edge = std::stod(col[7]);
    rows.push_back(r);
  }
  return rows;
}

Model load(const std::string& name) {
  return fs::host::build_model(
      fs::read_mesh(fs::test::shared_data() / "polyhedra/polyhedra-viewer/off" / (name + ".off")));
}

TEST(Polyhedra, AllSolidsMatchIndex) {
  const auto rows = read_index();
  ASSERT_EQ(rows.size(), 120u);
  for (const auto& r : rows) {
    SCOPED_TRACE(r.name);
    const Model m = load(r.name);
    EXPECT_FALSE(m.open);
    EXPECT_EQ(static_cast<int>(m.face_count()), r.F);
    EXPECT_EQ(static_cast<int>(m.arc_count()), r.E);
    EXPECT_EQ(static_cast<int>(m.graph.nodes.size()), r.F);
    // Every edge of these solids has the same length: total border = E * edge length.
    EXPECT_NEAR(m.total_border(), r.E * r.edge, 1e-5 * r.E * r.edge);
    for (const auto& a : m.graph.arcs) EXPECT_NEAR(a.border, r.edge, 1e-3 * r.edge);
    // Face shapes: one loop per face, with the listed number of sides.
    std::map<int, int> sides;
    int vertex_uses = 0;
    for (const auto& f : m.faces) {
      ASSERT_EQ(f.loops.size(), 1u);
      sides[static_cast<int>(f.loops[0].size())]++;
      vertex_uses += static_cast<int>(f.loops[0].size());
    }
    EXPECT_EQ(sides, r.sides);
    EXPECT_EQ(vertex_uses, 2 * r.E);
    EXPECT_EQ(r.V - r.E + r.F, 2);
    // Convex solids: every outward normal points away from the volume centroid, every vertex lies behind
    // every face plane.
    for (const auto& f : m.faces) {
      EXPECT_NEAR(f.normal.norm(), 1.0, 1e-12);
      EXPECT_GT(f.normal.dot(f.centroid - m.center), 0.0);
      for (const auto& g : m.faces)
        for (const auto& p : g.loops[0]) EXPECT_LE(f.normal.dot(p) - f.offset, 1e-5);
    }
    // Per face, the arcs carry exactly its perimeter (closed surface).
    std::vector<double> border(m.face_count(), 0.0);
    for (const auto& a : m.graph.arcs) {
      border[static_cast<std::size_t>(a.a)] += a.border;
      border[static_cast<std::size_t>(a.b)] += a.border;
    }
    for (std::size_t i = 0; i < m.face_count(); ++i) EXPECT_NEAR(border[i], m.faces[i].perimeter, 1e-9);
    EXPECT_GT(m.volume, 0.0);
    EXPECT_EQ(m.symmetries.front(), fs::Mat3::Identity());
  }
}

TEST(Polyhedra, SymmetryGroupOrders) {
  const std::map<std::string, std::size_t> expected{{"cube", 24},
                                                    {"tetrahedron", 12},
                                                    {"octahedron", 24},
                                                    {"dodecahedron", 60},
                                                    {"icosahedron", 60},
                                                    {"square-pyramid", 4},
                                                    {"pentagonal-pyramid", 5},
                                                    {"triangular-prism", 6},
                                                    {"hexagonal-prism", 12},
                                                    {"square-antiprism", 8},
                                                    {"snub-cube", 24},
                                                    {"snub-dodecahedron", 60},
                                                    {"truncated-icosidodecahedron", 60},
                                                    {"triangular-bipyramid", 6},
                                                    {"pentagonal-rotunda", 5},
                                                    {"elongated-square-gyrobicupola", 8},
                                                    {"gyrate-rhombicosidodecahedron", 5},
                                                    {"truncated-tetrahedron", 12},
                                                    {"cuboctahedron", 24},
                                                    {"snub-disphenoid", 4},
                                                    {"sphenomegacorona", 2},
                                                    {"bilunabirotunda", 4}};
  for (const auto& [name, order] : expected) {
    SCOPED_TRACE(name);
    const Model m = load(name);
    EXPECT_EQ(m.symmetry_order(), order);
    // Every element is a rotation that maps each face onto a face.
    for (const auto& S : m.symmetries) {
      EXPECT_NEAR((S * S.transpose() - fs::Mat3::Identity()).norm(), 0.0, 1e-9);
      EXPECT_NEAR(S.determinant(), 1.0, 1e-9);
      for (const auto& f : m.faces) {
        bool hit = false;
        for (const auto& g : m.faces)
          hit = hit ||
                ((S * f.normal - g.normal).norm() < 1e-2 &&
                 (S * (f.centroid - m.center) - (g.centroid - m.center)).norm() < 1e-2 * m.bounding_radius);
        EXPECT_TRUE(hit);
      }
    }
    // A group: closed under composition, no duplicates.
    for (std::size_t i = 0; i < m.symmetries.size(); ++i)
      for (std::size_t j = 0; j < m.symmetries.size(); ++j) {
        const fs::Mat3 P = m.symmetries[i] * m.symmetries[j];
        std::size_t found = 0;
        for (const auto& S : m.symmetries) found += (S - P).norm() < 1e-2;
        EXPECT_EQ(found, 1u);
      }
  }
}

}  // namespace
