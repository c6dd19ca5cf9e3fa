// The generator's mesh behind a library's polycube model (scenes of polycubes from a .fslib): names parsed,
// the mesh in the model's frame and size, anything else refused naming the library and the model.
#include <gtest/gtest.h>

#include <cmath>

#include "host/library/library.hpp"
#include "host/library/polycubes.hpp"
#include "support/error_of.hpp"

namespace {

using namespace fs::host;
using fs::test::error_of;

TEST(PolycubeMeshOf, ParsesTheGeneratorsNames) {
  const auto id = parse_polycube_name("polycube-8-6922");
  ASSERT_TRUE(id.has_value());
  EXPECT_EQ(id->volume, 8);
  EXPECT_EQ(id->index, 6922u);
  EXPECT_EQ(parse_polycube_name(polycube_name(3, 2))->index, 2u);
  for (const char* bad :
       {"cube", "polycube-", "polycube-3", "polycube-3-", "polycube--1", "polycube-0-001", "polycube-3-000",
        "polycube-3-01x", "polycube-x-001", "Polycube-3-001", "polycube-3-1-2"})
    EXPECT_FALSE(parse_polycube_name(bad).has_value()) << bad;
}

TEST(PolycubeMeshOf, ReproducesEveryModelOfALibraryInItsFrame) {
  const auto all = enumerate_polycubes(5);
  for (double edge : {20.0, 7.5})
    for (std::size_t v = 0; v < all.size(); ++v)
      for (std::size_t i = 0; i < all[v].size(); ++i) {
        const std::string name = polycube_name(static_cast<int>(v + 1), i + 1);
        const Model m = polycube_model(all[v][i], edge, name);
        const fs::Mesh mesh = polycube_mesh_of(m, all, "lib.fslib");
        const fs::Mesh want = polycube_mesh(all[v][i], edge, name);
        ASSERT_EQ(mesh.faces, want.faces) << name;
        ASSERT_EQ(mesh.vertices.size(), want.vertices.size()) << name;
        for (std::size_t k = 0; k < want.vertices.size(); ++k)
          ASSERT_LT((mesh.vertices[k] - want.vertices[k]).norm(), 1e-9 * edge) << name;
        // The model built from the mesh is the library's model (up to the rounding of the edge).
        const Model rebuilt = build_model(mesh);
        ASSERT_EQ(rebuilt.face_count(), m.face_count()) << name;
        EXPECT_EQ(rebuilt.arc_count(), m.arc_count()) << name;
        EXPECT_EQ(rebuilt.symmetry_order(), m.symmetry_order()) << name;
        // (Face order may differ: build_model's order follows the vertices' rounding.)
        for (const auto& f : m.faces) {
          int same = 0;
          for (const auto& g : rebuilt.faces)
            same += (g.normal - f.normal).norm() < 1e-9 && std::abs(g.area - f.area) < 1e-9 * f.area &&
                    (g.centroid - f.centroid).norm() < 1e-9 * edge;
          EXPECT_EQ(same, 1) << name;
        }
      }
}

TEST(PolycubeMeshOf, RefusesModelsThatAreNotTheGeneratorsPolycube) {
  const auto all = enumerate_polycubes(4);
  const Model l = polycube_model(all[2][0], 20, polycube_name(3, 1));
  Model renamed = l;
  renamed.name = "elbow";
  EXPECT_EQ(error_of([&] { polycube_mesh_of(renamed, all, "lib.fslib"); }),
            "lib.fslib: model 'elbow': not a polycube (names are polycube-<volume>-<index>)");
  renamed.name = polycube_name(3, 2);  // the straight tricube's name on the elbow
  EXPECT_EQ(error_of([&] { polycube_mesh_of(renamed, all, "lib.fslib"); }),
            "lib.fslib: model 'polycube-3-002': its faces are not those of the generator's polycube 3-2");
  renamed.name = polycube_name(5, 1);
  EXPECT_EQ(error_of([&] { polycube_mesh_of(renamed, all, "lib.fslib"); }),
            "lib.fslib: model 'polycube-5-001': no such polycube among the generated ones (volume <= 4)");
  renamed.name = polycube_name(3, 3);
  EXPECT_EQ(error_of([&] { polycube_mesh_of(renamed, all, "lib.fslib"); }),
            "lib.fslib: model 'polycube-3-003': no such polycube among the generated ones (volume <= 4)");
}

}  // namespace
