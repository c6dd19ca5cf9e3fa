// Honest ambiguity (issue #20): an object whose view fits other models as well is reported once, as
// ambiguous, with its candidates and a confidence that is the fit times its share of the candidates' fits;
// a clearly identified object keeps its fit as its confidence.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "host/library/mesh_files.hpp"
#include "host/recognize/recognizer.hpp"
#include "host/recognize/report.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/scene.hpp"
#include "support/test_paths.hpp"

namespace {

using fs::host::rec::Hypothesis;
using fs::host::rec::RecognizeParams;
using fs::host::rec::Recognizer;

const fs::host::Library& shipped_library() {
  static const fs::host::Library lib =
      fs::host::load_or_build_library({(fs::test::source_dir() / "hw-sim/scenes/meshes").string()});
  return lib;
}

// The shipped library plus a second model of the cube's shape: no view can tell the two apart.
const fs::host::Library& library_with_a_copy_of_the_cube() {
  static const fs::host::Library lib = [] {
    fs::host::Library l = shipped_library();
    fs::host::Model copy = *l.find("cube");
    copy.name = "cube-copy";
    l.add(std::move(copy));
    return l;
  }();
  return lib;
}

// The shipped scene CUBE1 (a cube turned on the table), recognized against `lib`.
struct CubeScene {
  fs::host::OrganizedCloud cloud;
  fs::Plane table;
};
const CubeScene& cube_scene() {
  static const CubeScene s = [] {
    CubeScene c;
    fs::sim::Scene scene = fs::sim::load_scene(fs::test::source_dir() / "hw-sim/scenes/cube.json");
    fs::sim::resample_sweep(scene.calibration, 300);
    fs::sim::make_ground_truth_grid(scene, {.depth_noise_mm = 0.05, .seed = 3}).export_to(c.cloud);
    c.table = scene.calibration.table;
    return c;
  }();
  return s;
}

RecognizeParams params() {
  RecognizeParams p;
  p.threads = 2;
  return p;
}

std::string read_text(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

TEST(Ambiguity, ConfidenceIsTheFitTimesItsShareOfTheCandidatesFits) {
  Hypothesis h;
  h.verify.confidence = 0.9;
  EXPECT_FALSE(h.ambiguous());
  EXPECT_DOUBLE_EQ(h.confidence(), 0.9);  // one candidate: the fit
  h.alternatives = 1;
  h.alternative[0] = {3, 0.9};
  EXPECT_TRUE(h.ambiguous());
  EXPECT_DOUBLE_EQ(h.fit(), 0.9);
  EXPECT_DOUBLE_EQ(h.confidence(), 0.45);  // two that fit alike: half each
  EXPECT_DOUBLE_EQ(h.candidate_confidence(0.9), 0.45);
  h.alternatives = 2;
  h.alternative[1] = {4, 0.6};
  EXPECT_DOUBLE_EQ(h.confidence(), 0.9 * 0.9 / 2.4);
  EXPECT_DOUBLE_EQ(h.candidate_confidence(0.6), 0.6 * 0.6 / 2.4);
  // The candidates' confidences never add up to more than the best fit.
  EXPECT_LE(h.confidence() + h.candidate_confidence(0.9) + h.candidate_confidence(0.6), 0.9 + 1e-12);
}

TEST(Ambiguity, AClearlyIdentifiedObjectIsNotAmbiguousAndKeepsItsFit) {
  const CubeScene& s = cube_scene();
  Recognizer rec(shipped_library(), params(), s.cloud.points.size());
  const auto& r = rec.recognize(s.cloud, &s.table);
  ASSERT_EQ(r.objects.size(), 1u) << fs::host::rec::result_table(r, shipped_library());
  const Hypothesis& h = r.objects[0];
  EXPECT_EQ(shipped_library().models[static_cast<std::size_t>(h.model)].name, "cube");
  EXPECT_FALSE(h.ambiguous());
  EXPECT_DOUBLE_EQ(h.confidence(), h.verify.confidence);
  const nlohmann::json j = fs::host::rec::to_json(r, shipped_library());
  const auto& o = j["objects"][0];
  EXPECT_EQ(o["ambiguous"], false);
  EXPECT_DOUBLE_EQ(o["confidence"].get<double>(), h.verify.confidence);
  EXPECT_DOUBLE_EQ(o["fit"].get<double>(), h.verify.confidence);
  EXPECT_FALSE(o.contains("candidates"));
  EXPECT_FALSE(o.contains("alternatives"));
  EXPECT_EQ(fs::host::rec::result_table(r, shipped_library()).find("ambiguous"), std::string::npos);
}

TEST(Ambiguity, TwoModelsTheViewCannotTellApartGiveOneAmbiguousObjectWithBoth) {
  const CubeScene& s = cube_scene();
  Recognizer clear(shipped_library(), params(), s.cloud.points.size());
  const double fit_alone = clear.recognize(s.cloud, &s.table).objects.at(0).verify.confidence;

  const fs::host::Library& lib = library_with_a_copy_of_the_cube();
  Recognizer rec(lib, params(), s.cloud.points.size());
  const auto& r = rec.recognize(s.cloud, &s.table);
  const std::string table = fs::host::rec::result_table(r, lib);
  ASSERT_EQ(r.objects.size(), 1u) << "reported once\n" << table;
  const Hypothesis& h = r.objects[0];
  ASSERT_TRUE(h.ambiguous()) << table;
  ASSERT_EQ(h.alternatives, 1) << table;
  const std::string model = lib.models[static_cast<std::size_t>(h.model)].name;
  const std::string other = lib.models[static_cast<std::size_t>(h.alternative[0].model)].name;
  EXPECT_TRUE((model == "cube" && other == "cube-copy") || (model == "cube-copy" && other == "cube"))
      << table;
  // The same fit as without the copy, and about half of it as the confidence: "cube or cube-copy".
  EXPECT_NEAR(h.fit(), fit_alone, 0.01);
  EXPECT_NEAR(h.alternative[0].fit, h.fit(), 0.02);
  EXPECT_NEAR(h.confidence(), 0.5 * h.fit(), 0.02);

  const nlohmann::json j = fs::host::rec::to_json(r, lib);
  ASSERT_EQ(j["objects"].size(), 1u);
  const auto& o = j["objects"][0];
  EXPECT_EQ(o["model"], model);  // a reader of "model" alone gets the best candidate
  EXPECT_EQ(o["ambiguous"], true);
  EXPECT_DOUBLE_EQ(o["fit"].get<double>(), h.fit());
  EXPECT_DOUBLE_EQ(o["confidence"].get<double>(), h.confidence());
  ASSERT_EQ(o["candidates"].size(), 2u) << o.dump();
  EXPECT_EQ(o["candidates"][0]["model"], model);
  EXPECT_DOUBLE_EQ(o["candidates"][0]["confidence"].get<double>(), h.confidence());
  EXPECT_EQ(o["candidates"][1]["model"], other);
  EXPECT_DOUBLE_EQ(o["candidates"][1]["fit"].get<double>(), h.alternative[0].fit);
  // Each candidate in its own pose: the object's for the first, the alternative's (the copy of the cube: the
  // same place, up to the cube's symmetry) for the second.
  for (int i = 0; i < 3; ++i) {
    EXPECT_DOUBLE_EQ(o["candidates"][0]["translation"][i].get<double>(), h.t[i]);
    EXPECT_DOUBLE_EQ(o["candidates"][1]["translation"][i].get<double>(), h.alternative[0].t[i]);
    EXPECT_DOUBLE_EQ(o["candidates"][1]["rotation"][i][i].get<double>(), h.alternative[0].R(i, i));
  }
  const fs::Vec3 c = lib.models[static_cast<std::size_t>(h.model)].center;
  EXPECT_LT((h.alternative[0].R * c + h.alternative[0].t - (h.R * c + h.t)).norm(), 1.0);
  ASSERT_EQ(o["alternatives"].size(), 1u);
  EXPECT_EQ(o["alternatives"][0]["model"], other);

  EXPECT_NE(table.find("ambiguous: " + model), std::string::npos) << table;
  EXPECT_NE(table.find(" or " + other), std::string::npos) << table;
  const auto dir =
      std::filesystem::temp_directory_path() / ("facetscan-ambiguity-" + std::to_string(::getpid()));
  fs::host::rec::write_report(dir, "cube", s.cloud, rec, r);
  const std::string html = read_text(dir / "index.html");
  std::filesystem::remove_all(dir);
  EXPECT_NE(html.find("ambiguous: " + model), std::string::npos);
  EXPECT_NE(html.find(" or " + other), std::string::npos);
}

}  // namespace
