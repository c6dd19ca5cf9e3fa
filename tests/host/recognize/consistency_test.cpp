// A physically possible answer (issue #20): accepted solids do not interpenetrate, and one model that
// explains the points of smaller ones and more replaces them.
#include <gtest/gtest.h>

#include <fstream>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "host/io/load.hpp"
#include "host/library/mesh_files.hpp"
#include "host/recognize/recognizer.hpp"
#include "host/recognize/report.hpp"
#include "host/recognize/verify.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/scene.hpp"
#include "support/test_paths.hpp"

namespace {

using fs::Mat3;
using fs::Vec3;
using fs::host::rec::interpenetration;
using fs::host::rec::ModelGeometry;

const fs::host::Library& shipped_library() {
  static const fs::host::Library lib =
      fs::host::load_or_build_library({(fs::test::source_dir() / "hw-sim/scenes/meshes").string()});
  return lib;
}

const fs::host::Model& model_named(const fs::host::Library& lib, const std::string& name) {
  for (const auto& m : lib.models)
    if (m.name == name) return m;
  throw std::runtime_error("no model " + name);
}

TEST(Interpenetration, TouchingCubesDoNotOverlapNestedOnesDo) {
  const auto& cube = model_named(shipped_library(), "cube");
  const ModelGeometry g(cube);
  ASSERT_TRUE(g.convex());
  ASSERT_FALSE(g.volume_samples().empty());
  const double side = std::cbrt(cube.volume);
  const Mat3 I = Mat3::Identity();
  // Side by side, touching: nothing inside the other.
  const auto touching = interpenetration(g, I, Vec3::Zero(), g, I, Vec3(side, 0, 0));
  EXPECT_LT(touching.depth_mm, 1e-6);
  EXPECT_LT(touching.volume_share, 1e-9);
  // Shifted by three quarters of a side: a quarter of the volume in the other; the centre of the face inside
  // lies a quarter side deep.
  const auto quarter = interpenetration(g, I, Vec3::Zero(), g, I, Vec3(0.75 * side, 0, 0));
  EXPECT_NEAR(quarter.volume_share, 0.25, 0.08);
  EXPECT_NEAR(quarter.depth_mm, 0.25 * side, 0.02 * side);
  // The same place: all of it.
  const auto same = interpenetration(g, I, Vec3::Zero(), g, I, Vec3::Zero());
  EXPECT_GT(same.volume_share, 0.99);
  // Far apart: nothing (and the bounding-sphere test skips the samples).
  const auto far = interpenetration(g, I, Vec3::Zero(), g, I, Vec3(10 * side, 0, 0));
  EXPECT_EQ(far.volume_share, 0.0);
  EXPECT_EQ(far.depth_mm, 0.0);
}

// Every shipped scene: no two accepted objects interpenetrate.
TEST(Consistency, NoTwoAcceptedObjectsInterpenetrateInTheShippedScenes) {
  fs::host::rec::RecognizeParams params;
  params.threads = 2;
  for (const char* name :
       {"cube", "pyramid", "corner", "cube-pyramid-separate", "cube-occludes-pyramid", "default"}) {
    fs::sim::Scene scene =
        fs::sim::load_scene(fs::test::source_dir() / "hw-sim/scenes" / (std::string(name) + ".json"));
    fs::sim::resample_sweep(scene.calibration, 300);
    fs::host::OrganizedCloud cloud;
    fs::sim::make_ground_truth_grid(scene, {.depth_noise_mm = 0.05, .seed = 3}).export_to(cloud);
    const fs::Plane table = scene.calibration.table;
    fs::host::rec::Recognizer rec(shipped_library(), params, cloud.points.size());
    const auto& r = rec.recognize(cloud, &table);
    EXPECT_FALSE(r.objects.empty()) << name;
    for (std::size_t a = 0; a < r.objects.size(); ++a)
      for (std::size_t b = a + 1; b < r.objects.size(); ++b) {
        const auto& oa = r.objects[a];
        const auto& ob = r.objects[b];
        const ModelGeometry ga(shipped_library().models[static_cast<std::size_t>(oa.model)]);
        const ModelGeometry gb(shipped_library().models[static_cast<std::size_t>(ob.model)]);
        const auto ip = interpenetration(ga, oa.R, oa.t, gb, ob.R, ob.t);
        EXPECT_FALSE(ip.depth_mm > params.interpenetration_mm &&
                     ip.volume_share > params.interpenetration_share)
            << name << ": objects " << a << " and " << b << " overlap " << ip.volume_share * 100 << " %, "
            << ip.depth_mm << " mm";
      }
  }
}

// A scan from an independent renderer (../shared/data/independent-scans): a biaugmented triangular prism that
// two octahedra in one place explained, and an elongated pentagonal rotunda split into two other models,
// before the replacement and the interpenetration test. Now exactly the three objects of its ground truth, in
// pose.
TEST(Consistency, IndependentClutterScanGivesExactlyItsObjects) {
  const auto dir = fs::test::shared_data() / "independent-scans";
  if (!std::filesystem::exists(dir / "clutter-01.pcd")) GTEST_SKIP() << "no " << dir.string();
  const fs::host::Library lib = fs::host::load_or_build_library({(dir / "library").string()});
  fs::host::OrganizedCloud cloud;
  fs::host::load_cloud((dir / "clutter-01.pcd").string(), cloud);
  fs::host::rec::RecognizeParams params;
  params.threads = 2;
  fs::host::rec::Recognizer rec(lib, params, cloud.points.size());
  const auto& r = rec.recognize(cloud, nullptr);

  std::ifstream in(dir / "clutter-01.truth.json");
  const nlohmann::json truth = nlohmann::json::parse(in);
  ASSERT_EQ(r.objects.size(), truth["objects"].size()) << fs::host::rec::result_table(r, lib);
  std::set<std::size_t> matched;
  for (const auto& t : truth["objects"]) {
    Vec3 pos;
    for (int i = 0; i < 3; ++i) pos[i] = t["translation"][i];
    Mat3 R;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) R(i, j) = t["rotation"][i][j];
    const auto& m = model_named(lib, t["model"]);
    const Vec3 centre = R * m.center + pos;
    bool found = false;
    for (std::size_t k = 0; k < r.objects.size(); ++k) {
      const auto& o = r.objects[k];
      if (lib.models[static_cast<std::size_t>(o.model)].name != t["model"]) continue;
      found = (o.R * m.center + o.t - centre).norm() < 3.0;
      if (found) matched.insert(k);
    }
    EXPECT_TRUE(found) << t["model"] << "\n" << fs::host::rec::result_table(r, lib);
  }
  EXPECT_EQ(matched.size(), r.objects.size());
  EXPECT_GE(r.stats.replaced, 1);
}

}  // namespace
