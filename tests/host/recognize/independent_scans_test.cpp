// The scans of an independent renderer (../shared/data/independent-scans, see its README): every object of
// the ground truth is reported once, as its model or as an ambiguous object that names its model among the
// candidates, and nothing else is reported. lookalike-01 holds a gyrate rhombicosidodecahedron whose
// look-alikes (the trigyrate one, ...) differ only in cupolae that may be out of view: the search kept only
// wrong placements of its model (the gyrated cupola where the scan shows an ordinary one), until the
// near-symmetric placements were verified too (reseat.cpp).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "host/io/load.hpp"
#include "host/library/mesh_files.hpp"
#include "host/recognize/recognizer.hpp"
#include "host/recognize/report.hpp"
#include "support/test_paths.hpp"

namespace {

using fs::Mat3;
using fs::Vec3;

std::filesystem::path scans() { return fs::test::shared_data() / "independent-scans"; }

const fs::host::Library& library() {
  static const fs::host::Library lib = fs::host::load_or_build_library({(scans() / "library").string()});
  return lib;
}

const fs::host::Model& model_named(const std::string& name) {
  const fs::host::Model* m = library().find(name);
  if (!m) throw std::runtime_error("no model " + name);
  return *m;
}

struct Scan {
  fs::host::rec::Recognition result;
  std::string table;
  nlohmann::json truth;
};

Scan recognize(const std::string& stem, const fs::host::rec::RecognizeParams& params) {
  fs::host::OrganizedCloud cloud;
  fs::host::load_cloud((scans() / (stem + ".pcd")).string(), cloud);
  fs::host::rec::Recognizer rec(library(), params, cloud.points.size());
  Scan s{rec.recognize(cloud, nullptr), {}, {}};
  s.table = fs::host::rec::result_table(s.result, library());
  std::ifstream in(scans() / (stem + ".truth.json"));
  s.truth = nlohmann::json::parse(in);
  return s;
}

fs::host::rec::RecognizeParams default_params() {
  fs::host::rec::RecognizeParams p;
  p.threads = 2;
  return p;
}

// The reported object at truth object t (by its model's centre, within 10 mm) whose model or an alternative
// is t's model; -1 when none.
int object_for(const Scan& s, const nlohmann::json& t) {
  const std::string name = t["model"];
  Vec3 pos;
  Mat3 R;
  for (int i = 0; i < 3; ++i) {
    pos[i] = t["translation"][i];
    for (int j = 0; j < 3; ++j) R(i, j) = t["rotation"][i][j];
  }
  const Vec3 centre = R * model_named(name).center + pos;
  int found = -1;
  for (std::size_t k = 0; k < s.result.objects.size(); ++k) {
    const auto& o = s.result.objects[k];
    const auto& m = library().models[static_cast<std::size_t>(o.model)];
    if ((o.R * m.center + o.t - centre).norm() > 10.0) continue;
    bool candidate = m.name == name;
    for (const auto& a : o.listed_alternatives())
      candidate = candidate || library().models[static_cast<std::size_t>(a.model)].name == name;
    if (candidate) found = static_cast<int>(k);
  }
  return found;
}

// Every truth object has its reported object, and each reported object stands for one truth object.
void expect_truth(const std::string& stem, const Scan& s) {
  EXPECT_EQ(s.result.objects.size(), s.truth["objects"].size()) << stem << "\n" << s.table;
  std::vector<int> claimed(s.result.objects.size(), 0);
  for (const auto& t : s.truth["objects"]) {
    const int k = object_for(s, t);
    EXPECT_GE(k, 0) << stem << ": " << t["model"] << " is no candidate of an object there\n" << s.table;
    if (k >= 0) ++claimed[static_cast<std::size_t>(k)];
  }
  for (std::size_t k = 0; k < claimed.size(); ++k)
    EXPECT_EQ(claimed[k], 1) << stem << ": object " << k + 1 << " stands for " << claimed[k]
                             << " objects of the truth\n"
                             << s.table;
}

const nlohmann::json& truth_object(const Scan& s, const std::string& model) {
  for (const auto& t : s.truth["objects"])
    if (t["model"] == model) return t;
  throw std::runtime_error("no " + model + " in the truth");
}

TEST(IndependentScans, ClutterGivesExactlyItsThreeObjects) {
  if (!std::filesystem::exists(scans() / "clutter-01.pcd")) GTEST_SKIP() << "no " << scans().string();
  expect_truth("clutter-01", recognize("clutter-01", default_params()));
}

TEST(IndependentScans, LookalikeGyrateRhombicosidodecahedronIsOneObjectWithItsModelAmongTheCandidates) {
  if (!std::filesystem::exists(scans() / "lookalike-01.pcd")) GTEST_SKIP() << "no " << scans().string();
  const Scan s = recognize("lookalike-01", default_params());
  expect_truth("lookalike-01", s);
  EXPECT_GE(s.result.stats.reseated, 1);
  // Without the near-symmetric placements, with t9.3's search cost and without the placement check (the
  // version that failed): the trigyrate one at confidence 1.00, without the gyrate one among its candidates.
  // (With the area cost, or with the placement check, the search itself brings the gyrate one's
  // correspondence into the pool.)
  fs::host::rec::RecognizeParams without = default_params();
  without.near_symmetry_share = 0.0;
  without.area_cost = -1.0;
  without.placement.rms_mm = 0.0;
  const Scan before = recognize("lookalike-01", without);
  EXPECT_LT(object_for(before, truth_object(before, "gyrate-rhombicosidodecahedron")), 0) << before.table;
  EXPECT_EQ(before.result.stats.reseated, 0);
}

}  // namespace
