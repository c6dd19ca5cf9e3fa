// Scene JSON parsing and the shipped scenes.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "common/error.hpp"
#include "common/input_file.hpp"
#include "common/mesh_io.hpp"
#include "hw-sim/scene/scene.hpp"
#include "support/error_of.hpp"
#include "support/test_paths.hpp"

namespace {

using ::testing::HasSubstr;
namespace fsys = std::filesystem;

fsys::path scenes_dir() { return fs::test::source_dir() / "hw-sim/scenes"; }

std::string scene_error(const std::string& json_text) {
  try {
    fs::sim::parse_scene(nlohmann::json::parse(json_text), scenes_dir(), "t.json");
  } catch (const fs::Error& e) {
    return e.what();
  }
  return "(no error)";
}

// 2D convex hull (monotone chain) of the objects' footprints, to check that objects don't interpenetrate.
std::vector<fs::Vec2> footprint(const fs::sim::SceneObject& o) {
  std::vector<fs::Vec2> p;
  for (const auto& f : o.faces)
    for (const auto& v : f.polygon) p.emplace_back(v.x(), v.y());
  std::sort(p.begin(), p.end(), [](const fs::Vec2& a, const fs::Vec2& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  auto cross = [](const fs::Vec2& o, const fs::Vec2& a, const fs::Vec2& b) {
    return (a - o).x() * (b - o).y() - (a - o).y() * (b - o).x();
  };
  std::vector<fs::Vec2> h(2 * p.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (std::size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross(h[k - 2], h[k - 1], p[i - 1]) <= 0) --k;
    h[k++] = p[i - 1];
  }
  h.resize(k - 1);
  return h;
}

// Separation (> 0 apart, 0 touching, < 0 overlapping) of two convex polygons by the separating axis theorem.
double separation(const std::vector<fs::Vec2>& a, const std::vector<fs::Vec2>& b) {
  double best = -1e300;
  for (const auto* poly : {&a, &b})
    for (std::size_t i = 0; i < poly->size(); ++i) {
      const fs::Vec2 e = (*poly)[(i + 1) % poly->size()] - (*poly)[i];
      const fs::Vec2 n = fs::Vec2(e.y(), -e.x()).normalized();
      double amin = 1e300, amax = -1e300, bmin = 1e300, bmax = -1e300;
      for (const auto& p : a) amin = std::min(amin, n.dot(p)), amax = std::max(amax, n.dot(p));
      for (const auto& p : b) bmin = std::min(bmin, n.dot(p)), bmax = std::max(bmax, n.dot(p));
      best = std::max({best, bmin - amax, amin - bmax});
    }
  return best;
}

TEST(Scene, ShippedScenesLoadAndRestOnTheTable) {
  const char* names[] = {"corner", "pyramid", "cube", "cube-pyramid-separate", "cube-occludes-pyramid",
                         "default"};
  for (const char* name : names) {
    SCOPED_TRACE(name);
    const fs::sim::Scene s = fs::sim::load_scene(scenes_dir() / (std::string(name) + ".json"));
    ASSERT_FALSE(s.objects.empty());
    EXPECT_TRUE(s.has_table);
    for (const auto& o : s.objects) {
      EXPECT_EQ(fs::check_closed_manifold(o.mesh), "") << o.name;
      EXPECT_GT(fs::mesh_signed_volume(o.mesh), 0.0) << o.name;
      EXPECT_NEAR(o.bounds.min().z(), 0.0, 1e-6) << o.name << " must rest on the table";
      EXPECT_GE(o.bounds.min().x(), -150.0);
      EXPECT_LE(o.bounds.max().x(), 150.0);
      EXPECT_GE(o.bounds.min().y(), -150.0);
      EXPECT_LE(o.bounds.max().y(), 150.0);
      const double size = (o.bounds.max() - o.bounds.min()).maxCoeff();
      EXPECT_GE(size, 40.0);
      EXPECT_LE(size, 100.0);
      // Outward normals: the world polygons (wound along their normals) enclose a positive volume.
      double v6 = 0.0;
      for (const auto& f : o.faces) {
        for (const auto& v : f.polygon) EXPECT_NEAR(f.plane.signed_distance(v), 0.0, 1e-9);
        fs::Vec3 n = fs::Vec3::Zero();
        for (std::size_t k = 0; k < f.polygon.size(); ++k)
          n += f.polygon[k].cross(f.polygon[(k + 1) % f.polygon.size()]);
        EXPECT_GT(n.dot(f.plane.n), 0.0) << o.name;
        for (std::size_t k = 1; k + 1 < f.polygon.size(); ++k)
          v6 += f.polygon[0].dot(f.polygon[k].cross(f.polygon[k + 1]));
      }
      EXPECT_NEAR(v6 / 6.0, fs::mesh_signed_volume(o.mesh), 1e-6 * std::abs(v6)) << o.name;
    }
    for (std::size_t i = 0; i < s.objects.size(); ++i)
      for (std::size_t j = i + 1; j < s.objects.size(); ++j)
        EXPECT_GE(separation(footprint(s.objects[i]), footprint(s.objects[j])), -1e-6)
            << s.objects[i].name << " and " << s.objects[j].name << " interpenetrate";
  }
}

TEST(Scene, DefaultSceneHasDifferentTouchingObjects) {
  const fs::sim::Scene s = fs::sim::load_scene(scenes_dir() / "default.json");
  ASSERT_GE(s.objects.size(), 3u);
  ASSERT_LE(s.objects.size(), 4u);
  std::set<std::string> names;
  for (const auto& o : s.objects) names.insert(o.name);
  EXPECT_EQ(names.size(), s.objects.size());
  double closest = 1e300;
  for (std::size_t i = 0; i < s.objects.size(); ++i)
    for (std::size_t j = i + 1; j < s.objects.size(); ++j)
      closest = std::min(closest, separation(footprint(s.objects[i]), footprint(s.objects[j])));
  EXPECT_NEAR(closest, 0.0, 1e-6) << "two objects touch";
}

TEST(Scene, PosesFromMatrixAndQuaternionAgree) {
  const auto a = fs::sim::parse_scene(nlohmann::json::parse(R"({"objects":[{"model":"cube",
      "rotation":[[0,-1,0],[1,0,0],[0,0,1]],"translation":[10,20,0]}]})"),
                                      scenes_dir(), "a.json");
  const double h = std::sqrt(0.5);
  const auto b = fs::sim::parse_scene(
      nlohmann::json::parse(R"({"objects":[{"model":"meshes/cube.off","quaternion":[)" + std::to_string(h) +
                            "," + "0,0," + std::to_string(h) + R"(],"translation":[10,20,0]}]})"),
      scenes_dir(), "b.json");
  ASSERT_EQ(a.objects.size(), 1u);
  ASSERT_EQ(b.objects.size(), 1u);
  EXPECT_TRUE(a.objects[0].rotation.isApprox(b.objects[0].rotation, 1e-6));
  for (std::size_t f = 0; f < a.objects[0].faces.size(); ++f)
    for (std::size_t k = 0; k < a.objects[0].faces[f].polygon.size(); ++k)
      EXPECT_TRUE(a.objects[0].faces[f].polygon[k].isApprox(b.objects[0].faces[f].polygon[k], 1e-6));
  // x_world = R x_model + t: the model vertex (25, -25, 0) goes to (25 + 10, 25 + 20, 0).
  bool found = false;
  for (const auto& f : a.objects[0].faces)
    for (const auto& v : f.polygon) found = found || (v - fs::Vec3(35, 45, 0)).norm() < 1e-9;
  EXPECT_TRUE(found);
}

TEST(Scene, ScannerOverridesAndTable) {
  const auto s = fs::sim::parse_scene(nlohmann::json::parse(R"({"objects":[],
      "scanner":{"steps":200,"camera":{"width":640,"height":480,"fx":800,"position":[0,0,450]},
                 "laser":{"axis_point":[180,0,450]}},
      "table":{"normal":[0,0,1],"d":5}})"),
                                      scenes_dir(), "s.json");
  EXPECT_EQ(s.calibration.step_count, 200u);
  EXPECT_EQ(s.calibration.camera.width, 640u);
  EXPECT_EQ(s.calibration.camera.height, 480u);
  EXPECT_EQ(s.calibration.camera.fx, 800.0);
  EXPECT_EQ(s.calibration.camera.t_world_cam, fs::Vec3(0, 0, 450));
  EXPECT_EQ(s.calibration.laser.axis_point, fs::Vec3(180, 0, 450));
  EXPECT_EQ(s.calibration.table.d, 5.0);
  const auto def = fs::ScannerCalibration::bench_default(200);
  EXPECT_DOUBLE_EQ(s.calibration.laser.rad_per_step, def.laser.rad_per_step);
  const auto no_table =
      fs::sim::parse_scene(nlohmann::json::parse(R"({"objects":[],"table":false})"), scenes_dir(), "n");
  EXPECT_FALSE(no_table.has_table);
}

TEST(Scene, ErrorsNameFileAndField) {
  EXPECT_THAT(scene_error(R"({})"), HasSubstr("t.json: objects: missing"));
  EXPECT_THAT(scene_error(R"({"objects":{}})"), HasSubstr("t.json: objects: expected an array"));
  EXPECT_THAT(scene_error(R"({"objects":[{}]})"),
              HasSubstr("t.json: objects[0].model: expected a mesh path"));
  EXPECT_THAT(scene_error(R"({"objects":[{"model":"cube","rotation":[[1,0,0],[0,1,0]]}]})"),
              HasSubstr("objects[0].rotation: expected a 3x3 array"));
  EXPECT_THAT(scene_error(R"({"objects":[{"model":"cube","rotation":[[1,0,0],[0,2,0],[0,0,1]]}]})"),
              HasSubstr("objects[0].rotation: not a rotation"));
  EXPECT_THAT(scene_error(R"({"objects":[{"model":"cube","rotation":[[1,0,0],[0,1,0],[0,0,-1]]}]})"),
              HasSubstr("objects[0].rotation: not a rotation"));
  EXPECT_THAT(scene_error(R"({"objects":[{"model":"cube","quaternion":[0,0,0,0]}]})"),
              HasSubstr("objects[0].quaternion: zero quaternion"));
  EXPECT_THAT(scene_error(R"({"objects":[{"model":"cube","translation":[1,"x",3]}]})"),
              HasSubstr("objects[0].translation[1]: expected a number"));
  EXPECT_THAT(scene_error(R"({"objects":[{"model":"cube"},{"model":"nope.off"}]})"),
              HasSubstr("objects[1].model: "));
  EXPECT_THAT(scene_error(R"({"objects":[{"model":"nope.off"}]})"), HasSubstr("cannot open mesh file"));
  EXPECT_THAT(scene_error(R"({"objects":[{"model":"cube","colour":1}]})"),
              HasSubstr("objects[0].colour: unknown field"));
  EXPECT_THAT(scene_error(R"({"objects":[],"scanner":{"steps":0}})"), HasSubstr("scanner.steps: must be in"));
  EXPECT_THAT(scene_error(R"({"objects":[],"scanner":{"camera":{"fx":-1}}})"),
              HasSubstr("scanner.camera.fx: must be positive"));
  EXPECT_THAT(scene_error(R"({"objects":[],"scanner":{"laser":{"axis_dir":[0,0,0]}}})"),
              HasSubstr("scanner.laser.axis_dir: zero-length"));
  EXPECT_THAT(scene_error(R"({"objects":[],"table":{"normal":[0,0,1],"d":"low"}})"),
              HasSubstr("table.d: expected a number"));
  EXPECT_THAT(scene_error(R"({"objects":[{"model":"cube","scale":1e300}]})"),
              HasSubstr("objects[0].model: "));
  EXPECT_THAT(scene_error(R"({"objects":[{"model":"cube","scale":1e300}]})"), HasSubstr("out of range"));
  // A bad file: JSON syntax error with the byte offset.
  const auto p = fsys::temp_directory_path() / ("fs_scene_test_" + std::to_string(::getpid()) + ".json");
  std::ofstream(p) << "{\"objects\": [ }";
  try {
    fs::sim::load_scene(p);
    ADD_FAILURE() << "no error";
  } catch (const fs::Error& e) {
    EXPECT_THAT(e.what(), HasSubstr(p.string() + ": at byte "));
    EXPECT_THAT(e.what(), HasSubstr("invalid JSON"));
  }
  fsys::remove(p);
  EXPECT_THROW(fs::sim::load_scene("/nonexistent/scene.json"), fs::Error);
}

TEST(SceneJson, LinksToDevicesAndOversizedFilesAreRefused) {
  const auto dir = fsys::temp_directory_path() / ("fs_scene_inputs_" + std::to_string(::getpid()));
  fsys::remove_all(dir);
  fsys::create_directories(dir);
  fsys::create_symlink("/dev/zero", dir / "zero.json");
  EXPECT_EQ(fs::test::error_of([&] { fs::sim::load_scene(dir / "zero.json"); }),
            (dir / "zero.json").string() + ": not a regular file (character device)");
  const auto big = dir / "big.json";
  { std::ofstream(big) << "{}"; }
  fsys::resize_file(big, fs::kMaxConfigFileBytes + 1);  // sparse
  EXPECT_EQ(fs::test::error_of([&] { fs::sim::load_scene(big); }),
            big.string() + ": 1.0 MB, more than the 1 MiB a scene file may have");
  fsys::remove_all(dir);
}

}  // namespace
