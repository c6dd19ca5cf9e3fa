// Cluttered random scenes (hw-sim/scene/cluttered_scene.hpp) over many seeds: 3-6 objects in a dense cluster,
// no two solids interpenetrating (exact test), every stacked object resting stably on an upward face of an
// object on the table, deterministic per seed; the ground truth sees the upper object of a stack.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "hw-sim/scene/cluttered_scene.hpp"
#include "hw-sim/scene/convex_separation.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/random_scene.hpp"
#include "support/test_paths.hpp"

namespace {

using fs::Vec2;
using fs::Vec3;
using fs::sim::SceneCategory;

constexpr int kSeeds = 60;

const std::vector<fs::sim::CatalogEntry>& catalog() {
  static const auto c = fs::sim::make_catalog(
      fs::sim::read_catalog_meshes(fs::test::shared_data() / "polyhedra/polyhedra-viewer/off"), {.seed = 1});
  return c;
}

fs::sim::RandomScene cluttered(std::uint64_t seed, std::uint32_t steps = 100) {
  return fs::sim::make_random_scene(catalog(), {.category = SceneCategory::cluttered, .steps = steps}, seed);
}

// Vertical projection of a planar polygon onto the table.
std::vector<Vec2> flat(const std::vector<Vec3>& polygon) {
  std::vector<Vec2> out;
  for (const auto& x : polygon) out.emplace_back(x.x(), x.y());
  return out;
}

bool inside(const Vec3& point, const std::vector<Vec3>& polygon) {
  return fs::sim::polygon_distance({Vec2(point.x(), point.y())}, flat(polygon)) == 0.0;
}

// Independent of the separating-axis test: a vertex of `a` strictly inside the solid `b`.
bool vertex_inside(const fs::sim::SceneObject& a, const fs::sim::SceneObject& b) {
  for (const auto& fa : a.faces)
    for (const auto& x : fa.polygon) {
      bool in = true;
      for (const auto& fb : b.faces) in = in && fb.plane.signed_distance(x) < -1e-3;
      if (in) return true;
    }
  return false;
}

Vec3 world_centroid(const fs::sim::RandomScene& rs, std::size_t i) {
  const auto& ob = rs.scene.objects[i];
  return ob.rotation * catalog()[static_cast<std::size_t>(rs.catalog_index[i])].centroid + ob.translation;
}

// Checks one scene; returns the number of stacked objects.
int check_cluttered(const fs::sim::RandomScene& rs) {
  const fs::sim::RandomSceneOptions o{.category = SceneCategory::cluttered};
  const auto& objs = rs.scene.objects;
  EXPECT_GE(static_cast<int>(objs.size()), o.clutter_min_objects);
  EXPECT_LE(static_cast<int>(objs.size()), o.clutter_max_objects);
  EXPECT_EQ(rs.catalog_index.size(), objs.size());
  EXPECT_EQ(rs.resting_face.size(), objs.size());
  EXPECT_EQ(rs.support.size(), objs.size());
  EXPECT_EQ(rs.support_face.size(), objs.size());
  std::vector<fs::sim::ConvexShape> shapes;
  for (const auto& ob : objs) shapes.push_back(fs::sim::ConvexShape::of(ob));

  int stacked = 0;
  for (std::size_t i = 0; i < objs.size(); ++i) {
    SCOPED_TRACE("object " + std::to_string(i) + " " + objs[i].name);
    const auto& ob = objs[i];
    EXPECT_GE(rs.catalog_index[i], 0);
    EXPECT_GE(ob.bounds.min().x(), o.x_min - 1e-9);
    EXPECT_LE(ob.bounds.max().x(), o.x_max + 1e-9);
    EXPECT_GE(ob.bounds.min().y(), o.y_min - 1e-9);
    EXPECT_LE(ob.bounds.max().y(), o.y_max + 1e-9);
    const auto& down = ob.faces.at(static_cast<std::size_t>(rs.resting_face[i]));
    const Vec3 c = world_centroid(rs, i);
    if (rs.support[i] < 0) {  // on the table, stable
      EXPECT_EQ(rs.support_face[i], -1);
      EXPECT_NEAR(ob.bounds.min().z(), 0.0, 1e-6);
      EXPECT_LT((down.plane.n - Vec3(0, 0, -1)).norm(), 1e-6);
      EXPECT_TRUE(inside(c, down.polygon)) << "tips over";
      continue;
    }
    // Stacked: on an upward face of an object on the table, resting face on its plane, centroid above both.
    ++stacked;
    const auto base = static_cast<std::size_t>(rs.support[i]);
    EXPECT_LT(base, i) << "placed before what it carries";
    if (base >= i) continue;
    EXPECT_EQ(rs.support[base], -1) << "one level only";
    const auto& top = objs[base].faces.at(static_cast<std::size_t>(rs.support_face[i]));
    EXPECT_GE(top.plane.n.z(), std::cos(o.stack_max_tilt_deg * std::numbers::pi / 180.0) - 1e-12);
    EXPECT_LT((down.plane.n + top.plane.n).norm(), 1e-6);
    for (const auto& x : down.polygon) EXPECT_NEAR(top.plane.signed_distance(x), 0.0, 1e-3);
    EXPECT_GT(ob.bounds.min().z(), 0.0) << "touches the table";
    EXPECT_TRUE(inside(c, top.polygon)) << "centroid beside the supporting face";
    EXPECT_TRUE(inside(c, down.polygon)) << "centroid beside its resting face";
    // The base with its load does not tip over.
    double volume = 0;
    Vec3 moment = Vec3::Zero();
    for (std::size_t j = 0; j < objs.size(); ++j)
      if (j == base || rs.support[j] == static_cast<int>(base)) {
        const double v = catalog()[static_cast<std::size_t>(rs.catalog_index[j])].volume_mm3;
        volume += v;
        moment += v * world_centroid(rs, j);
      }
    EXPECT_TRUE(
        inside(moment / volume, objs[base].faces.at(static_cast<std::size_t>(rs.resting_face[base])).polygon))
        << "the base tips over";
  }

  // No pair interpenetrates (exact test and the independent vertex test); every table object after the first
  // is within the clutter gap of an earlier solid.
  std::vector<std::vector<double>> sep(objs.size(), std::vector<double>(objs.size(), 0.0));
  for (std::size_t i = 0; i < objs.size(); ++i)
    for (std::size_t j = i + 1; j < objs.size(); ++j) {
      sep[i][j] = sep[j][i] = fs::sim::separation(shapes[i], shapes[j]);
      EXPECT_GE(sep[i][j], -fs::sim::kTouchingTolerance_mm) << objs[i].name << " and " << objs[j].name;
      EXPECT_FALSE(vertex_inside(objs[i], objs[j])) << objs[i].name << " in " << objs[j].name;
      EXPECT_FALSE(vertex_inside(objs[j], objs[i])) << objs[j].name << " in " << objs[i].name;
    }
  for (std::size_t i = 1; i < objs.size(); ++i)
    if (rs.support[i] < 0) {
      const double nearest_earlier = *std::min_element(sep[i].begin(), sep[i].begin() + static_cast<long>(i));
      EXPECT_LE(nearest_earlier, o.clutter_gap_max_mm + 1e-6) << "object " << i << " is not in the cluster";
    }
  return stacked;
}

TEST(ClutteredScene, ManySeedsGiveValidDenseScenesSomeStacked) {
  int stacked_scenes = 0, objects = 0;
  for (std::uint64_t seed = 1; seed <= kSeeds; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const auto rs = cluttered(seed);
    EXPECT_EQ(rs.category, SceneCategory::cluttered);
    EXPECT_EQ(rs.scene.calibration.step_count, 100u);
    const int stacked = check_cluttered(rs);
    EXPECT_LE(stacked, 1);
    stacked_scenes += stacked > 0 ? 1 : 0;
    objects += static_cast<int>(rs.scene.objects.size());
  }
  EXPECT_GE(stacked_scenes, kSeeds / 4);
  EXPECT_GT(objects, 4 * kSeeds - kSeeds / 2);  // 3-6 each, about 4.5 on average
}

TEST(ClutteredScene, DeterministicPerSeed) {
  const auto a = cluttered(42), b = cluttered(42), c = cluttered(43);
  ASSERT_EQ(a.scene.objects.size(), b.scene.objects.size());
  EXPECT_EQ(a.support, b.support);
  EXPECT_EQ(a.catalog_index, b.catalog_index);
  for (std::size_t i = 0; i < a.scene.objects.size(); ++i) {
    EXPECT_EQ(a.scene.objects[i].rotation, b.scene.objects[i].rotation);
    EXPECT_EQ(a.scene.objects[i].translation, b.scene.objects[i].translation);
  }
  EXPECT_NE(a.catalog_index, c.catalog_index);
  EXPECT_EQ(fs::sim::parse_scene_category("cluttered"), SceneCategory::cluttered);
}

TEST(ClutteredScene, NoStackWhenAskedForNone) {
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    const auto rs = fs::sim::make_random_scene(
        catalog(), {.category = SceneCategory::cluttered, .stacked_objects = 0}, seed);
    EXPECT_TRUE(std::all_of(rs.support.begin(), rs.support.end(), [](int s) { return s == -1; }));
  }
}

TEST(ClutteredScene, GroundTruthSeesTheUpperObjectOfAStack) {
  std::uint64_t seed = 1;
  fs::sim::RandomScene rs;
  for (; seed <= kSeeds; ++seed) {
    rs = cluttered(seed, 150);
    if (std::any_of(rs.support.begin(), rs.support.end(), [](int s) { return s >= 0; })) break;
  }
  ASSERT_LE(seed, static_cast<std::uint64_t>(kSeeds)) << "no stacked scene";
  SCOPED_TRACE("seed " + std::to_string(seed));
  const auto upper = static_cast<std::size_t>(
      std::find_if(rs.support.begin(), rs.support.end(), [](int s) { return s >= 0; }) - rs.support.begin());
  const auto base = static_cast<std::size_t>(rs.support[upper]);
  const auto gt = fs::sim::make_ground_truth_grid(rs.scene);
  const auto id = static_cast<std::int32_t>(upper + 1);
  EXPECT_GT(gt.count_object(id), 100u);
  // Its points lie on its faces, above the supporting plane; nothing is seen of the contact faces.
  const auto& top = rs.scene.objects[base].faces.at(static_cast<std::size_t>(rs.support_face[upper]));
  std::size_t on_upper = 0;
  for (const auto& cell : gt.cells()) {
    if (cell.object != id) continue;
    ++on_upper;
    const auto& f = rs.scene.objects[upper].faces.at(static_cast<std::size_t>(cell.face));
    EXPECT_NEAR(f.plane.signed_distance(cell.true_point), 0.0, 1e-4);  // OFF files: 7 digits
    EXPECT_GT(top.plane.signed_distance(cell.true_point), -1e-4);
    EXPECT_GT(cell.true_point.z(), 0.0);
  }
  EXPECT_EQ(on_upper, gt.count_object(id));
  EXPECT_EQ(gt.count_face(id, rs.resting_face[upper]), 0u);
}

}  // namespace
