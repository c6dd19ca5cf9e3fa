// Random scenes of polycubes (hw-sim/scene/polycube_catalog.hpp): mass properties of non-convex meshes,
// resting planes made of several coplanar unit squares (possibly apart), objects on the table and never
// interpenetrating (checked on the unit cells themselves), at the library's size and in its models' frame.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "host/library/polycubes.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/polycube_catalog.hpp"
#include "hw-sim/scene/random_scene.hpp"

namespace {

using fs::Mat3;
using fs::Vec3;
using fs::host::Polycube;
using fs::sim::SceneCategory;

constexpr double kEdge = 20.0;

fs::Mesh mesh_of(const Polycube& cells) { return fs::host::polycube_mesh(cells, kEdge, "p"); }

// Outward normals (unit, axis-aligned) of the stable resting planes.
std::vector<Vec3> resting_normals(const fs::Mesh& m) {
  const auto mass = fs::sim::solid_mass(m);
  std::vector<Vec3> out;
  for (int f : fs::sim::stable_resting_faces(m, mass))
    out.push_back(fs::sim::outward_normal(m, static_cast<std::size_t>(f), mass.centroid));
  return out;
}
bool has(const std::vector<Vec3>& v, const Vec3& n) {
  return std::any_of(v.begin(), v.end(), [&](const Vec3& x) { return (x - n).norm() < 1e-9; });
}

TEST(PolycubeScene, MassOfNonConvexMeshesEitherWinding) {
  // An L of three cubes: volume 3, centroid the mean of the cell centres.
  const Polycube l{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  fs::Mesh m = mesh_of(l);
  auto mass = fs::sim::solid_mass(m);
  EXPECT_NEAR(mass.volume, 3 * kEdge * kEdge * kEdge, 1e-6);
  EXPECT_LT((mass.centroid - kEdge * Vec3(5.0 / 6, 5.0 / 6, 0.5)).norm(), 1e-9);
  EXPECT_FALSE(mass.inward);
  for (auto& f : m.faces) std::reverse(f.begin(), f.end());
  mass = fs::sim::solid_mass(m);
  EXPECT_TRUE(mass.inward);
  EXPECT_NEAR(mass.volume, 3 * kEdge * kEdge * kEdge, 1e-6);
  EXPECT_LT((mass.centroid - kEdge * Vec3(5.0 / 6, 5.0 / 6, 0.5)).norm(), 1e-9);
  // Resting planes do not depend on the winding either.
  EXPECT_EQ(fs::sim::stable_resting_faces(m, mass).size(), resting_normals(mesh_of(l)).size());
}

TEST(PolycubeScene, RestingPlaneOfSeveralSquaresIsStableWhereNoSingleSquareIs) {
  // A 2 x 2 x 1 slab: the centroid projects onto the corner the four bottom squares share, strictly inside
  // none of them (make_catalog's one-face rule finds no stable face), but inside their hull: 6 planes.
  const fs::Mesh slab = mesh_of({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}});
  const auto mass = fs::sim::solid_mass(slab);
  for (std::size_t f = 0; f < slab.faces.size(); ++f)
    EXPECT_FALSE(fs::sim::is_stable_face(slab, f, mass.centroid, 0.5)) << f;
  EXPECT_EQ(resting_normals(slab).size(), 6u);

  // A U standing on two legs apart: rests on the hull of both feet. Lying on its side it rests as well; on
  // its open side (the legs' ends, +z) too; the concavity's floor is no resting plane.
  const Polycube u{{0, 0, 0}, {0, 0, 1}, {0, 0, 2}, {1, 0, 2}, {2, 0, 2}, {2, 0, 1}, {2, 0, 0}};
  const auto n = resting_normals(mesh_of(u));
  EXPECT_TRUE(has(n, Vec3(0, 0, -1)));  // on the feet
  EXPECT_TRUE(has(n, Vec3(0, 0, 1)));   // upside down, on the bridge
  EXPECT_TRUE(has(n, Vec3(0, 1, 0)));
  EXPECT_TRUE(has(n, Vec3(0, -1, 0)));
  EXPECT_TRUE(has(n, Vec3(1, 0, 0)));  // on a leg's side
  EXPECT_EQ(n.size(), 6u);
}

TEST(PolycubeScene, OverhangingShapeIsUnstableOnItsFoot) {
  // One cube under the end of a bar of three: the centroid (x = 1.25 edges) is beyond the foot (x <= 1).
  const Polycube t{{0, 0, 0}, {0, 0, 1}, {1, 0, 1}, {2, 0, 1}};
  const auto n = resting_normals(mesh_of(t));
  EXPECT_FALSE(has(n, Vec3(0, 0, -1)));
  EXPECT_TRUE(has(n, Vec3(0, 0, 1)));  // on the bar
  EXPECT_TRUE(has(n, Vec3(0, 1, 0)));  // flat on its side
}

TEST(PolycubeScene, EveryPolycubeUpToVolumeSixHasARestingPlane) {
  const auto all = fs::host::enumerate_polycubes(6);
  std::vector<fs::Mesh> meshes;
  for (std::size_t v = 0; v < all.size(); ++v)
    for (std::size_t i = 0; i < all[v].size(); ++i)
      meshes.push_back(fs::host::polycube_mesh(all[v][i], kEdge, fs::host::polycube_name(int(v + 1), i + 1)));
  const auto catalog = fs::sim::make_polycube_catalog(meshes);
  ASSERT_EQ(catalog.size(), 1u + 1 + 2 + 8 + 29 + 166);
  for (std::size_t k = 0; k < catalog.size(); ++k) {
    EXPECT_FALSE(catalog[k].stable_faces.empty()) << meshes[k].name;
    EXPECT_EQ(catalog[k].mesh.vertices, meshes[k].vertices) << "no scaling: " << meshes[k].name;
  }
  EXPECT_EQ(catalog[0].stable_faces.size(), 6u);  // the cube
  EXPECT_NEAR(catalog[0].size_mm, kEdge * std::sqrt(3.0), 1e-9);
}

// True when a point strictly inside one of a's unit cells lies inside one of b's cells (solids posed as in
// the scene: x_world = R x_model + t).
bool cells_overlap(const Polycube& a, const fs::sim::SceneObject& oa, const Polycube& b,
                   const fs::sim::SceneObject& ob) {
  const double eps = 1e-6;
  for (const auto& c : a)
    for (int s = 0; s < 27; ++s) {
      const Vec3 local =
          kEdge * (Vec3(c[0], c[1], c[2]) +
                   Vec3(0.05 + 0.45 * (s % 3), 0.05 + 0.45 * (s / 3 % 3), 0.05 + 0.45 * (s / 9)));
      const Vec3 in_b =
          ob.rotation.transpose() * (oa.rotation * local + oa.translation - ob.translation) / kEdge;
      for (const auto& d : b)
        if (in_b.x() > d[0] + eps && in_b.x() < d[0] + 1 - eps && in_b.y() > d[1] + eps &&
            in_b.y() < d[1] + 1 - eps && in_b.z() > d[2] + eps && in_b.z() < d[2] + 1 - eps)
          return true;
    }
  return false;
}

TEST(PolycubeScene, RandomScenesRestOnTheTableAndNeverInterpenetrate) {
  const auto all = fs::host::enumerate_polycubes(6);
  std::vector<Polycube> cells;
  std::vector<fs::Mesh> meshes;
  for (std::size_t v = 3; v < all.size(); ++v)  // volumes 4-6
    for (std::size_t i = 0; i < all[v].size(); ++i) {
      cells.push_back(all[v][i]);
      meshes.push_back(fs::host::polycube_mesh(all[v][i], kEdge, fs::host::polycube_name(int(v + 1), i + 1)));
    }
  const auto catalog = fs::sim::make_polycube_catalog(meshes);
  {  // the check sees an overlap: an object with itself, or shifted by half an edge
    auto rs = fs::sim::make_random_scene(catalog, {.category = SceneCategory::single, .steps = 50}, 1);
    const auto& o = rs.scene.objects.at(0);
    const auto& c = cells[static_cast<std::size_t>(rs.catalog_index[0])];
    EXPECT_TRUE(cells_overlap(c, o, c, o));
    auto shifted = o;
    shifted.translation += Vec3(0.5 * kEdge, 0, 0);
    EXPECT_TRUE(cells_overlap(c, o, c, shifted));
    shifted.translation += Vec3(0, 0, 10 * kEdge);
    EXPECT_FALSE(cells_overlap(c, o, c, shifted));
  }
  int objects = 0, touching_pairs = 0;
  for (auto cat : {SceneCategory::single, SceneCategory::separated, SceneCategory::occluded})
    for (std::uint64_t seed = 1; seed <= 25; ++seed) {
      const auto rs = fs::sim::make_random_scene(catalog, {.category = cat, .steps = 50}, seed);
      const auto& objs = rs.scene.objects;
      ASSERT_GE(objs.size(), 1u);
      for (std::size_t i = 0; i < objs.size(); ++i) {
        ++objects;
        const auto ci = static_cast<std::size_t>(rs.catalog_index[i]);
        // On the table, on the chosen plane: the resting face looks down and lies in z = 0 (with every square
        // of that plane), nothing below it.
        double zmin = 1e300;
        for (const auto& f : objs[i].faces)
          for (const auto& x : f.polygon) zmin = std::min(zmin, x.z());
        EXPECT_NEAR(zmin, 0.0, 1e-9);
        const auto& rest = objs[i].faces[static_cast<std::size_t>(rs.resting_face[i])];
        EXPECT_LT((rest.plane.n - Vec3(0, 0, -1)).norm(), 1e-9);
        for (const auto& x : rest.polygon) EXPECT_NEAR(x.z(), 0.0, 1e-9);
        // Its centroid above its contact hull (the resting plane was stable): inside the footprint.
        const Vec3 c = objs[i].rotation * catalog[ci].centroid + objs[i].translation;
        const auto fp = fs::sim::footprint(objs[i]);
        EXPECT_EQ(fs::sim::polygon_distance(fp, {fs::Vec2(c.x(), c.y())}), 0.0);
        for (std::size_t j = i + 1; j < objs.size(); ++j) {
          const auto cj = static_cast<std::size_t>(rs.catalog_index[j]);
          const double gap = fs::sim::polygon_distance(fp, fs::sim::footprint(objs[j]));
          EXPECT_GT(gap, 0.0);
          touching_pairs += gap < 3.5;
          EXPECT_FALSE(cells_overlap(cells[ci], objs[i], cells[cj], objs[j])) << "seed " << seed;
          EXPECT_FALSE(cells_overlap(cells[cj], objs[j], cells[ci], objs[i])) << "seed " << seed;
        }
      }
    }
  EXPECT_GT(objects, 100);
  EXPECT_GT(touching_pairs, 10);  // the occluded scenes put polycubes next to each other
}

TEST(PolycubeScene, ThePolycubeIsSeenInTheGroundTruth) {
  const auto all = fs::host::enumerate_polycubes(5);
  std::vector<fs::Mesh> meshes;
  for (std::size_t i = 0; i < all[4].size(); ++i)
    meshes.push_back(fs::host::polycube_mesh(all[4][i], kEdge, fs::host::polycube_name(5, i + 1)));
  const auto catalog = fs::sim::make_polycube_catalog(meshes);
  const auto rs = fs::sim::make_random_scene(catalog, {.category = SceneCategory::single, .steps = 120}, 3);
  const auto gt = fs::sim::make_ground_truth_grid(rs.scene);
  EXPECT_GT(gt.count_object(1), 500u);
  // Every cell of the object lies on one of its quads (face id = quad index).
  for (const auto& c : gt.cells())
    if (c.object == 1) {
      const auto& f = rs.scene.objects[0].faces.at(static_cast<std::size_t>(c.face));
      ASSERT_NEAR(f.plane.signed_distance(c.true_point), 0.0, 1e-6);
    }
}

}  // namespace
