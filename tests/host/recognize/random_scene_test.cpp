// The random scene generator of the recognition benchmark: sizes, stable resting faces, objects on the table,
// inside the placement rectangle, never interpenetrating, touching when asked, deterministic per seed.
#include <gtest/gtest.h>

#include <algorithm>

#include "common/error.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/random_scene.hpp"
#include "support/test_paths.hpp"

namespace {

using fs::Vec2;
using fs::Vec3;
using fs::sim::SceneCategory;

const std::vector<fs::sim::CatalogEntry>& catalog() {
  static const auto c = fs::sim::make_catalog(
      fs::sim::read_catalog_meshes(fs::test::shared_data() / "polyhedra/polyhedra-viewer/off"), {.seed = 5});
  return c;
}

double max_extent(const fs::Mesh& m) {
  double d = 0;
  for (const auto& a : m.vertices)
    for (const auto& b : m.vertices) d = std::max(d, (a - b).norm());
  return d;
}

// Independent 3D check: a vertex of `a` strictly inside the convex solid `b` (behind all its face planes).
bool vertex_inside(const fs::sim::SceneObject& a, const fs::sim::SceneObject& b, double margin) {
  for (const auto& fa : a.faces)
    for (const auto& x : fa.polygon) {
      bool inside = true;
      for (const auto& fb : b.faces) inside = inside && fb.plane.signed_distance(x) < -margin;
      if (inside) return true;
    }
  return false;
}

TEST(RandomScene, CatalogHasAllPolyhedraScaledWithStableFaces) {
  const auto& c = catalog();
  ASSERT_EQ(c.size(), 120u);
  for (const auto& e : c) {
    EXPECT_GE(e.size_mm, 40.0) << e.mesh.name;
    EXPECT_LE(e.size_mm, 80.0) << e.mesh.name;
    EXPECT_NEAR(max_extent(e.mesh), e.size_mm, 1e-6) << e.mesh.name;
    EXPECT_FALSE(e.stable_faces.empty()) << e.mesh.name;
  }
  const auto cube = std::find_if(c.begin(), c.end(), [](const auto& e) { return e.mesh.name == "cube"; });
  ASSERT_NE(cube, c.end());
  EXPECT_EQ(cube->stable_faces.size(), 6u);
  EXPECT_LT(cube->centroid.norm(), 1e-9);
}

TEST(RandomScene, LeaningPrismIsUnstableOnItsBase) {
  // A parallelepiped whose top is shifted 30 mm over a 10 mm base: the centroid (x = 20) is outside the base.
  fs::Mesh m;
  m.name = "leaning";
  m.vertices = {{0, 0, 0},   {10, 0, 0},  {10, 10, 0},  {0, 10, 0},
                {30, 0, 10}, {40, 0, 10}, {40, 10, 10}, {30, 10, 10}};
  m.faces = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
  const Vec3 c = fs::sim::volume_centroid(m);
  EXPECT_NEAR(c.x(), 20.0, 1e-9);
  EXPECT_NEAR(c.z(), 5.0, 1e-9);
  EXPECT_FALSE(fs::sim::is_stable_face(m, 0, c));  // base
  EXPECT_FALSE(fs::sim::is_stable_face(m, 1, c));  // top
  EXPECT_TRUE(fs::sim::is_stable_face(m, 2, c));   // the long slanted side (y = 0)
  EXPECT_TRUE((fs::sim::outward_normal(m, 0, c) - Vec3(0, 0, -1)).norm() < 1e-12);
}

TEST(RandomScene, PolygonDistance) {
  const std::vector<Vec2> a{{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  const std::vector<Vec2> b{{3, 0}, {4, 0}, {4, 1}, {3, 1}};
  const std::vector<Vec2> c{{0.5, 0.5}, {2, 0.5}, {2, 2}, {0.5, 2}};
  EXPECT_NEAR(fs::sim::polygon_distance(a, b), 2.0, 1e-12);
  EXPECT_EQ(fs::sim::polygon_distance(a, c), 0.0);
}

void check_scene(const fs::sim::RandomScene& rs, const fs::sim::RandomSceneOptions& o) {
  const auto& objs = rs.scene.objects;
  ASSERT_EQ(objs.size(), rs.catalog_index.size());
  if (o.category == SceneCategory::single) {
    EXPECT_EQ(objs.size(), 1u);
  }
  if (o.category == SceneCategory::separated || o.category == SceneCategory::occluded) {
    EXPECT_GE(static_cast<int>(objs.size()), o.min_objects);
    EXPECT_LE(static_cast<int>(objs.size()), o.max_objects);
  }
  if (o.category == SceneCategory::empty) {
    EXPECT_LE(objs.size(), 1u);
    for (int ci : rs.catalog_index) EXPECT_EQ(ci, -1);
  }
  std::vector<std::vector<Vec2>> prints;
  for (std::size_t i = 0; i < objs.size(); ++i) {
    const auto& ob = objs[i];
    // On the table: lowest point at z = 0, a face lying on it.
    EXPECT_NEAR(ob.bounds.min().z(), 0.0, 1e-6);
    EXPECT_GE(ob.bounds.min().x(), o.x_min - 1e-9);
    EXPECT_LE(ob.bounds.max().x(), o.x_max + 1e-9);
    EXPECT_GE(ob.bounds.min().y(), o.y_min - 1e-9);
    EXPECT_LE(ob.bounds.max().y(), o.y_max + 1e-9);
    if (rs.catalog_index[i] >= 0) {
      const auto& e = catalog()[static_cast<std::size_t>(rs.catalog_index[i])];
      EXPECT_EQ(ob.name, e.mesh.name);
      const auto& down = ob.faces.at(static_cast<std::size_t>(rs.resting_face[i]));
      EXPECT_LT((down.plane.n - Vec3(0, 0, -1)).norm(), 1e-6) << ob.name;
      for (const auto& x : down.polygon) EXPECT_NEAR(x.z(), 0.0, 1e-4);  // OFF files have 7 digits
      // Stable: the world centroid projects inside the resting face (checked on the posed object).
      const Vec3 c = ob.rotation * e.centroid + ob.translation;
      std::vector<Vec2> face2;
      for (const auto& x : down.polygon) face2.emplace_back(x.x(), x.y());
      const std::vector<Vec2> point{Vec2(c.x(), c.y())};
      EXPECT_EQ(fs::sim::polygon_distance(point, face2), 0.0) << ob.name << " tips over";
    }
    prints.push_back(fs::sim::footprint(ob));
  }
  double closest = 1e300;
  for (std::size_t i = 0; i < objs.size(); ++i)
    for (std::size_t j = i + 1; j < objs.size(); ++j) {
      const double d = fs::sim::polygon_distance(prints[i], prints[j]);
      closest = std::min(closest, d);
      EXPECT_FALSE(vertex_inside(objs[i], objs[j], 1e-6)) << objs[i].name << " in " << objs[j].name;
      EXPECT_FALSE(vertex_inside(objs[j], objs[i], 1e-6)) << objs[j].name << " in " << objs[i].name;
      if (o.category == SceneCategory::separated) {
        EXPECT_GE(d, o.separation_mm - 1e-9);
      }
      if (o.category == SceneCategory::occluded) {
        EXPECT_GE(d, o.touch_gap_min_mm - 1e-6);
      }
    }
  // Occluded scenes: every object was placed touching a neighbour, so the closest pair is within the gap.
  if (o.category == SceneCategory::occluded && objs.size() >= 2) {
    EXPECT_LE(closest, o.touch_gap_max_mm + 1e-3);
  }
}

TEST(RandomScene, EveryCategoryGivesValidScenes) {
  for (auto cat :
       {SceneCategory::single, SceneCategory::separated, SceneCategory::occluded, SceneCategory::empty})
    for (std::uint64_t seed = 1; seed <= 25; ++seed) {
      const fs::sim::RandomSceneOptions o{.category = cat, .steps = 100};
      SCOPED_TRACE(std::string(fs::sim::to_string(cat)) + " seed " + std::to_string(seed));
      const auto rs = fs::sim::make_random_scene(catalog(), o, seed);
      EXPECT_EQ(rs.scene.calibration.step_count, 100u);
      check_scene(rs, o);
    }
}

TEST(RandomScene, DeterministicPerSeed) {
  const fs::sim::RandomSceneOptions o{.category = SceneCategory::occluded};
  const auto a = fs::sim::make_random_scene(catalog(), o, 42);
  const auto b = fs::sim::make_random_scene(catalog(), o, 42);
  const auto c = fs::sim::make_random_scene(catalog(), o, 43);
  ASSERT_EQ(a.scene.objects.size(), b.scene.objects.size());
  for (std::size_t i = 0; i < a.scene.objects.size(); ++i) {
    EXPECT_EQ(a.scene.objects[i].name, b.scene.objects[i].name);
    EXPECT_EQ(a.scene.objects[i].rotation, b.scene.objects[i].rotation);
    EXPECT_EQ(a.scene.objects[i].translation, b.scene.objects[i].translation);
  }
  bool differs = a.scene.objects.size() != c.scene.objects.size();
  for (std::size_t i = 0; !differs && i < a.scene.objects.size(); ++i)
    differs = a.scene.objects[i].translation != c.scene.objects[i].translation;
  EXPECT_TRUE(differs);
}

TEST(RandomScene, SingleObjectIsSeenByTheScanner) {
  const auto rs = fs::sim::make_random_scene(catalog(), {.category = SceneCategory::single, .steps = 120}, 7);
  const auto gt = fs::sim::make_ground_truth_grid(rs.scene, {.depth_noise_mm = 0.05, .seed = 7});
  EXPECT_GT(gt.count_object(1), 200u);
  EXPECT_GT(gt.count_object(0), 1000u);  // the table
}

TEST(RandomScene, BadArgumentsAreErrors) {
  EXPECT_THROW(fs::sim::parse_scene_category("crowded"), fs::Error);
  EXPECT_THROW(fs::sim::read_catalog_meshes(fs::test::source_dir() / "no-such-dir"), fs::Error);
  EXPECT_THROW(fs::sim::make_random_scene({}, {.category = SceneCategory::single}, 1), fs::Error);
  EXPECT_THROW(fs::sim::make_random_scene(
                   catalog(), {.category = SceneCategory::separated, .min_objects = 3, .max_objects = 2}, 1),
               fs::Error);
}

}  // namespace
