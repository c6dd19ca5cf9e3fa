// A physically possible answer (issue #20): accepted solids do not interpenetrate, and one model that
// explains the points of smaller ones and more replaces them.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <numbers>
#include <random>
#include <set>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "host/io/load.hpp"
#include "host/library/mesh_files.hpp"
#include "host/library/model.hpp"
#include "host/recognize/recognizer.hpp"
#include "host/recognize/report.hpp"
#include "host/recognize/support.hpp"
#include "host/recognize/verify.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/random_scene.hpp"
#include "hw-sim/scene/scene.hpp"
#include "support/segment_by_cells.hpp"
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

TEST(Interpenetration, AFacePlaneSeparatesOnlyAcrossAGap) {
  const auto& cube = model_named(shipped_library(), "cube");
  const ModelGeometry g(cube);
  const double side = std::cbrt(cube.volume);
  const Mat3 I = Mat3::Identity();
  // The other cube's vertices in this one's frame: x = I x_other + t.
  EXPECT_TRUE(g.separated_from(g, I, Vec3(side + 0.5, 0, 0), 0.01));
  EXPECT_FALSE(g.separated_from(g, I, Vec3(side + 0.005, 0, 0), 0.01));  // within the margin
  EXPECT_FALSE(g.separated_from(g, I, Vec3(side, 0, 0), 0.01));          // touching
  EXPECT_FALSE(g.separated_from(g, I, Vec3(0.75 * side, 0, 0), 0.01));
  // Turned 45 degrees about z and moved along the diagonal: only the corner edge points at this cube, and it
  // stays 1 mm clear of this cube's x face.
  const Mat3 Rz = Eigen::AngleAxisd(0.25 * std::numbers::pi, Vec3::UnitZ()).toRotationMatrix();
  const double reach = side / std::sqrt(2.0);
  EXPECT_TRUE(g.separated_from(g, Rz, Vec3(0.5 * side + reach + 1.0, 0, 0), 0.01));
  EXPECT_FALSE(g.separated_from(g, Rz, Vec3(0.5 * side + reach - 1.0, 0, 0), 0.01));
}

// The separating plane only skips the samples: over pairs of the shipped solids in random poses, apart,
// touching and overlapping, interpenetration() gives what sampling both solids against each other gives.
TEST(Interpenetration, TheSeparatingPlaneChangesNoResult) {
  const auto& lib = shipped_library();
  std::vector<ModelGeometry> geometry;
  for (const auto& m : lib.models) geometry.emplace_back(m);
  auto sampled = [](const ModelGeometry& a, const Mat3& Ra, const Vec3& ta, const ModelGeometry& b,
                    const Mat3& Rb, const Vec3& tb) {
    fs::host::rec::Interpenetration r;
    const Mat3 Rab = Rb.transpose() * Ra, Rba = Ra.transpose() * Rb;
    const Vec3 tab = Rb.transpose() * (ta - tb), tba = Ra.transpose() * (tb - ta);
    for (const Vec3& s : a.surface_samples())
      r.depth_mm = std::max(r.depth_mm, b.depth_inside(Rab * s + tab));
    for (const Vec3& s : b.surface_samples())
      r.depth_mm = std::max(r.depth_mm, a.depth_inside(Rba * s + tba));
    const bool a_small = a.model().volume <= b.model().volume;
    const ModelGeometry& small = a_small ? a : b;
    const ModelGeometry& large = a_small ? b : a;
    std::size_t in = 0;
    for (const Vec3& s : small.volume_samples())
      in += large.depth_inside((a_small ? Rab : Rba) * s + (a_small ? tab : tba)) > 0.0 ? 1 : 0;
    if (!small.volume_samples().empty())
      r.volume_share = static_cast<double>(in) / static_cast<double>(small.volume_samples().size());
    return r;
  };
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto rotation = [&] {
    return Mat3(
        Eigen::Quaterniond(
            Eigen::Vector4d(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5).normalized())
            .toRotationMatrix());
  };
  int apart = 0, overlapping = 0, trials = 0;
  for (int k = 0; k < 60; ++k) {
    const ModelGeometry& a = geometry[static_cast<std::size_t>(rng() % geometry.size())];
    const ModelGeometry& b = geometry[static_cast<std::size_t>(rng() % geometry.size())];
    if (!a.convex() || !b.convex()) continue;
    const Mat3 Ra = rotation(), Rb = rotation();
    Vec3 dir(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5);
    dir.normalize();
    const Vec3 ta = -Ra * a.center();
    auto tb_at = [&](double d) { return Vec3(d * dir - Rb * b.center()); };
    // Where along `dir` the sampled solids stop overlapping (convex: once apart, farther is apart too).
    double lo = 0.0, hi = a.radius() + b.radius();
    for (int it = 0; it < 40; ++it) {
      const double mid = 0.5 * (lo + hi);
      const auto m = sampled(a, Ra, ta, b, Rb, tb_at(mid));
      (m.depth_mm > 0.0 || m.volume_share > 0.0 ? lo : hi) = mid;
    }
    // Around the contact (within and beyond the separating plane's 0.01 mm margin), and anywhere.
    for (double delta : {-1.0, -0.1, -0.01, -0.003, 0.0, 0.003, 0.01, 0.02, 0.1, 1.0}) {
      const double d = delta == 1.0 ? unit(rng) * (a.radius() + b.radius()) : hi + delta;
      const Vec3 tb = tb_at(d);
      const auto got = interpenetration(a, Ra, ta, b, Rb, tb);
      const auto want = sampled(a, Ra, ta, b, Rb, tb);
      ASSERT_EQ(got.depth_mm, want.depth_mm) << a.model().name << " / " << b.model().name << " at " << d;
      ASSERT_EQ(got.volume_share, want.volume_share)
          << a.model().name << " / " << b.model().name << " at " << d;
      ++trials;
      apart += b.separated_from(a, Rb.transpose() * Ra, Rb.transpose() * (ta - tb), 0.01) ? 1 : 0;
      overlapping += want.depth_mm > 0.0 ? 1 : 0;
    }
  }
  // Both kinds of pair occur, so both paths ran.
  EXPECT_GT(trials, 300);
  EXPECT_GT(apart, trials / 20);
  EXPECT_GT(overlapping, trials / 10);
}

// A cube on a cube: it rests on the one below when a point of its resting face lies on that solid's surface
// and the lower one's centre is below its own (support.hpp).
TEST(Support, RestsOnTheSolidBelowIt) {
  using fs::host::rec::PosedModel;
  using fs::host::rec::rests_on;
  const auto& cube = model_named(shipped_library(), "cube");
  const ModelGeometry g(cube);
  const double side = std::cbrt(cube.volume);
  const fs::Plane table{Vec3::UnitZ(), 0.0};
  const Mat3 I = Mat3::Identity();
  const PosedModel below{&g, I, Vec3::Zero()};
  auto on = [&](const Vec3& t, const Mat3& R = Mat3::Identity()) {
    double lowest = std::numeric_limits<double>::infinity();
    for (const auto& f : cube.faces)
      for (const auto& loop : f.loops)
        for (const Vec3& v : loop) lowest = std::min(lowest, table.signed_distance(R * v + t));
    return rests_on({&g, R, t}, lowest, below, table, 3.0);
  };
  EXPECT_TRUE(on(Vec3(0, 0, side)));                 // squarely on top
  EXPECT_TRUE(on(Vec3(0.8 * side, 0, side + 2.0)));  // overhanging, 2 mm gap (within tolerance)
  EXPECT_FALSE(on(Vec3(0, 0, side + 10.0)));         // floating 10 mm above
  EXPECT_FALSE(on(Vec3(1.5 * side, 0, side)));       // beside it, at its top's height: nothing under it
  EXPECT_FALSE(rests_on(below, 0.0, {&g, I, Vec3(0, 0, side)}, table, 3.0));  // the lower one on the upper
  // Turned 45 degrees about the vertical, still on the top face.
  EXPECT_TRUE(on(Vec3(0, 0, side), Eigen::AngleAxisd(0.25 * M_PI, Vec3::UnitZ()).toRotationMatrix()));
}

// Cluttered benchmark scenes (bench_recognition --categories cluttered --seed 1000, 250 steps), recognized
// with the benchmark's library and parameters.
class ClutteredScenes : public ::testing::Test {
 protected:
  static constexpr std::uint32_t kSteps = 250;
  ClutteredScenes()
      : catalog_(fs::sim::make_catalog(
            fs::sim::read_catalog_meshes(fs::test::shared_data() / "polyhedra/polyhedra-viewer/off"),
            {.seed = 1000})),
        library_(library_of(catalog_)),
        rec_(library_, params(), std::size_t{kSteps} * fs::ScannerCalibration::bench_default().camera.height),
        rec_no_hidden_(library_, params_no_hidden_below(),
                       std::size_t{kSteps} * fs::ScannerCalibration::bench_default().camera.height) {}
  static fs::host::Library library_of(const std::vector<fs::sim::CatalogEntry>& catalog) {
    fs::host::Library lib;
    for (const auto& e : catalog) lib.add(fs::host::build_model(e.mesh));
    return lib;
  }
  static fs::host::rec::RecognizeParams params() {
    fs::host::rec::RecognizeParams p;
    p.threads = 2;
    return p;
  }
  // The mechanisms that the space hidden under a solid (RecognizeParams::support_hidden_below) would
  // otherwise take over in these scenes are tested without it.
  static fs::host::rec::RecognizeParams params_no_hidden_below() {
    fs::host::rec::RecognizeParams p = params();
    p.support_hidden_below = false;
    return p;
  }
  const fs::host::rec::Recognition& recognize(const fs::sim::RandomScene& rs, std::uint64_t seed,
                                              bool hidden_below = true) {
    fs::sim::make_ground_truth_grid(rs.scene, {.depth_noise_mm = 0.05, .seed = seed})
        .export_to(cloud_, false);
    const fs::Plane table = rs.scene.calibration.table;
    return (hidden_below ? rec_ : rec_no_hidden_).recognize(cloud_, &table);
  }
  fs::sim::RandomScene scene(std::uint64_t seed) const {
    return fs::sim::make_random_scene(catalog_,
                                      {.category = fs::sim::SceneCategory::cluttered, .steps = kSteps}, seed);
  }
  // Scene object oi is reported: its model, centre within 10 mm (the benchmark's "found").
  bool found(const fs::sim::RandomScene& rs, std::size_t oi, const fs::host::rec::Recognition& r) const {
    const auto& obj = rs.scene.objects[oi];
    const auto& truth = library_.models[static_cast<std::size_t>(rs.catalog_index[oi])];
    const Vec3 centre = obj.rotation * truth.center + obj.translation;
    for (const auto& h : r.objects) {
      const auto& m = library_.models[static_cast<std::size_t>(h.model)];
      if (m.name == truth.name && (h.R * m.center + h.t - centre).norm() < 10.0) return true;
    }
    return false;
  }
  // In each scene (seed, true solid), the true solid is not reported as itself but is among a reported
  // object's candidates in its own pose (centre within 10 mm), and not with the check off (`off`).
  void expect_listed_only_with_the_check(const fs::host::rec::RecognizeParams& off,
                                         std::initializer_list<std::pair<std::uint64_t, const char*>> cases) {
    fs::host::rec::Recognizer without(
        library_, off, std::size_t{kSteps} * fs::ScannerCalibration::bench_default().camera.height);
    int exercised = 0;
    for (const auto& [seed, name] : cases) {
      const auto rs = scene(seed);
      std::size_t oi = rs.scene.objects.size();
      for (std::size_t k = 0; k < rs.scene.objects.size(); ++k)
        if (library_.models[static_cast<std::size_t>(rs.catalog_index[k])].name == name) oi = k;
      ASSERT_LT(oi, rs.scene.objects.size()) << "seed " << seed << ": the benchmark scene changed";
      const auto& truth = library_.models[static_cast<std::size_t>(rs.catalog_index[oi])];
      const Vec3 centre = rs.scene.objects[oi].rotation * truth.center + rs.scene.objects[oi].translation;
      auto listed_near = [&](const fs::host::rec::Recognition& r) {
        for (const auto& h : r.objects)
          for (const auto& a : h.listed_alternatives())
            if (a.model == rs.catalog_index[oi] && (a.R * truth.center + a.t - centre).norm() < 10.0) {
              EXPECT_LT(h.confidence(), h.fit()) << "seed " << seed;  // "X or Y": less sure than the fit
              return true;
            }
        return false;
      };
      const auto& r = recognize(rs, seed);
      if (found(rs, oi, r)) continue;  // found as itself (a later improvement): nothing to list
      ++exercised;
      EXPECT_TRUE(listed_near(r)) << "seed " << seed << ": " << name << " is not among the candidates";
      fs::sim::make_ground_truth_grid(rs.scene, {.depth_noise_mm = 0.05, .seed = seed})
          .export_to(cloud_, false);
      const fs::Plane table = rs.scene.calibration.table;
      EXPECT_FALSE(listed_near(without.recognize(cloud_, &table)))
          << "seed " << seed << ": listed without the check";
    }
    EXPECT_GT(exercised, 0) << "the solids are now found as themselves: pick other scenes";
  }
  std::vector<fs::sim::CatalogEntry> catalog_;
  fs::host::Library library_;
  fs::host::rec::Recognizer rec_, rec_no_hidden_;
  fs::host::OrganizedCloud cloud_;
};

// One object rests on another: the one on top hides the face it rests on, so nothing is measured under it and
// the support test alone halves its confidence below min_confidence. Resting on the object below, accepted in
// the same decision, it is found: each scene gives exactly its objects (before: the stacked one was missed).
TEST_F(ClutteredScenes, StackedObjectsAreFound) {
  for (const std::uint64_t seed : {1011u, 1019u, 1025u, 1031u}) {
    const auto rs = scene(seed);
    ASSERT_NE(std::count_if(rs.support.begin(), rs.support.end(), [](int s) { return s >= 0; }), 0) << seed;
    const auto& r = recognize(rs, seed, false);
    EXPECT_EQ(r.objects.size(), rs.scene.objects.size()) << "seed " << seed;
    EXPECT_GE(r.stats.stacked, 1) << "seed " << seed;
    for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi)
      EXPECT_TRUE(found(rs, oi, r)) << "seed " << seed << ": " << rs.scene.objects[oi].name
                                    << (rs.support[oi] >= 0 ? " (resting on another object)"
                                                            : " (on the table)");
  }
}

// The object carrying another is hidden by it: most of its predicted surface lies behind the upper object's
// points (occluded rays), so its confidence stays below min_confidence; the upper one waits for support.
// Explained together (the occluding points belong to the object waiting to rest on it), both are found.
TEST_F(ClutteredScenes, ObjectsHiddenByWhatTheyCarryAreFound) {
  for (const std::uint64_t seed : {1001u, 1008u, 1021u}) {
    const auto rs = scene(seed);
    const auto& r = recognize(rs, seed);
    EXPECT_GE(r.stats.hidden, 1) << "seed " << seed;
    for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi) {
      const int on = rs.support[oi];
      if (on < 0) continue;
      EXPECT_TRUE(found(rs, oi, r)) << "seed " << seed << ": " << rs.scene.objects[oi].name << " on top";
      EXPECT_TRUE(found(rs, static_cast<std::size_t>(on), r))
          << "seed " << seed << ": " << rs.scene.objects[static_cast<std::size_t>(on)].name << " below";
    }
  }
}

// A look-alike accepted in an earlier round (a larger model claiming matter where free space was seen, or
// one spanning an object and part of its neighbour) meets, in a later round, a hypothesis that explains about
// as many of its points with fewer violations and a clearly higher confidence: it is replaced. Each scene
// gives exactly its objects (before: a wrong model each, and a missed object in three of them).
TEST_F(ClutteredScenes, ABetterFitOfTheSamePointsReplacesAnAcceptedLookAlike) {
  for (const std::uint64_t seed : {1009u, 1053u, 1151u, 1187u}) {
    const auto rs = scene(seed);
    const auto& r = recognize(rs, seed, false);
    EXPECT_EQ(r.objects.size(), rs.scene.objects.size()) << "seed " << seed;
    EXPECT_GE(r.stats.replaced, 1) << "seed " << seed;
    for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi)
      EXPECT_TRUE(found(rs, oi, r)) << "seed " << seed << ": " << rs.scene.objects[oi].name;
  }
}

// A look-alike that fits an accepted object's points as well but meets it only in a later round (so it was
// not among the alternatives of the round that accepted it) is listed as its alternative: the report says
// "this is X or Y" with the true model among the candidates (before: X alone at confidence 0.98).
TEST_F(ClutteredScenes, ALookAlikeOfALaterRoundIsListedAsAnAlternative) {
  const std::uint64_t seed = 1100;
  const auto rs = scene(seed);
  const auto& r = recognize(rs, seed, false);
  bool listed = false;
  for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi) {
    const auto& truth = library_.models[static_cast<std::size_t>(rs.catalog_index[oi])];
    if (truth.name != "pentagonal-gyrobicupola") continue;
    const Vec3 centre = rs.scene.objects[oi].rotation * truth.center + rs.scene.objects[oi].translation;
    for (const auto& h : r.objects) {
      const auto& m = library_.models[static_cast<std::size_t>(h.model)];
      if ((h.R * m.center + h.t - centre).norm() > 10.0) continue;
      EXPECT_TRUE(h.ambiguous()) << m.name;
      EXPECT_LT(h.confidence(), h.fit()) << m.name;  // "X or Y": less sure than the fit alone
      for (const auto& a : h.listed_alternatives())
        listed = listed || library_.models[static_cast<std::size_t>(a.model)].name == truth.name;
    }
  }
  EXPECT_TRUE(listed) << "the pentagonal gyrobicupola is not among the candidates";
}

// An object seen through a gap between its neighbours shows two faces that larger solids contain as well; it
// is accepted because the neighbours explain what hides the rest. The true solid (a gyroelongated square
// bipyramid, an elongated triangular gyrobicupola) fits those faces as well but was never verified: mostly
// hidden, it ranked low. Checked after the acceptance (RecognizeParams::hidden_alternatives), it is listed
// among the object's candidates in its own pose, within 10 mm of the truth, and the report is "X or Y"
// (before: X alone at full confidence, a false positive).
TEST_F(ClutteredScenes, ASolidSeenThroughAGapListsTheLargerSolidsThatFitIt) {
  fs::host::rec::RecognizeParams off = params();
  off.hidden_alternatives = 0;
  expect_listed_only_with_the_check(
      off, {{1001, "gyroelongated-square-bipyramid"}, {1097, "elongated-triangular-gyrobicupola"}});
}

// The same for an object accepted on its own fit, a quarter or more of whose rays met measured points in
// front of it (RecognizeParams::occluded_alternatives_share): the neighbours hide the part where a larger
// solid differs. An elongated pentagonal orthobicupola seen as the elongated pentagonal cupola it contains,
// an elongated pentagonal orthocupolarotunda as a pentagonal gyrocupolarotunda: each true solid is listed in
// its own pose (before: the smaller solid alone, a false positive). The alternatives' rule comparing fits
// without the occluded rays (alternative_seen_fit) lists both true solids too, so it is off with the check.
TEST_F(ClutteredScenes, ASolidPartlyHiddenByOthersListsTheLargerSolidsThatFitIt) {
  fs::host::rec::RecognizeParams off = params();
  off.occluded_alternatives_share = 2.0;
  off.alternative_seen_fit = false;
  expect_listed_only_with_the_check(
      off, {{1116, "elongated-pentagonal-orthobicupola"}, {1156, "elongated-pentagonal-orthocupolarotunda"}});
}

// A solid resting on an object of which almost nothing is in view (covered by it and by its neighbours):
// the supporter is not found, nothing measured lies under the solid's lowest point, and the support test
// halved its perfect fit. The space under that point is hidden from the sensor (rays end in front of it, none
// beyond), so it may rest there: found (before, and with support_hidden_below off: missed).
TEST_F(ClutteredScenes, ASolidOnASupporterOutOfViewIsFound) {
  for (const std::uint64_t seed : {1000u, 1004u, 1014u}) {
    const auto rs = scene(seed);
    std::size_t upper = rs.scene.objects.size();
    for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi)
      if (rs.support[oi] >= 0) upper = oi;
    ASSERT_LT(upper, rs.scene.objects.size()) << "seed " << seed << ": the benchmark scene changed";
    EXPECT_TRUE(found(rs, upper, recognize(rs, seed)))
        << "seed " << seed << ": " << rs.scene.objects[upper].name << " on top";
  }
  const auto rs = scene(1000);
  const auto& r = recognize(rs, 1000, false);
  for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi)
    if (rs.support[oi] >= 0) {
      EXPECT_FALSE(found(rs, oi, r)) << rs.scene.objects[oi].name;
    }
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
// pose. With the area cost the search finds the right models first; with the search cost of t9.3 (no area
// term) it does too now that the normals' span follows the scan's grid spacing, while with normals over 2
// cells (`by_cells`) the replacement is what gets there.
void expect_exactly_the_clutter_objects(double area_cost, bool by_cells, bool replaced) {
  const auto dir = fs::test::shared_data() / "independent-scans";
  const fs::host::Library lib = fs::host::load_or_build_library({(dir / "library").string()});
  fs::host::OrganizedCloud cloud;
  fs::host::load_cloud((dir / "clutter-01.pcd").string(), cloud);
  fs::host::rec::RecognizeParams params;
  params.threads = 2;
  params.area_cost = area_cost;
  if (by_cells) fs::test::segment_by_cells(params.segment);
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
  if (replaced) {
    EXPECT_GE(r.stats.replaced, 1);
  } else {
    EXPECT_EQ(r.stats.replaced, 0);
  }
}

TEST(Consistency, IndependentClutterScanGivesExactlyItsObjects) {
  const auto dir = fs::test::shared_data() / "independent-scans";
  if (!std::filesystem::exists(dir / "clutter-01.pcd")) GTEST_SKIP() << "no " << dir.string();
  expect_exactly_the_clutter_objects(fs::host::rec::RecognizeParams{}.area_cost, false, false);
  expect_exactly_the_clutter_objects(-1.0, false, false);
  expect_exactly_the_clutter_objects(-1.0, true, true);
}

}  // namespace
