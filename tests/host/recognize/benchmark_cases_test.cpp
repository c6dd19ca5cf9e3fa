// Scenes of the recognition benchmark (bench_recognition, catalog seed 1 unless named) that earlier versions
// got wrong, each with the baseline that fails, so the fix is pinned:
//  - seed 102 (separated, 250 steps): the triaugmented hexagonal prism's pyramid faces meet its squares
//  at 5.26
//    degrees; at the earlier 0.6 mm segmentation tolerance they merged and the triaugmented triangular prism
//    took the object;
//  - seed 89 (single, 500 steps): a hexagonal prism fits the prism part of the parabiaugmented hexagonal
//  prism
//    with the same confidence; the hypothesis explaining more points (inlier_weight) must go first.
#include <gtest/gtest.h>

#include <algorithm>

#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>
#include "host/library/library.hpp"
#include "host/library/model.hpp"

#include "host/recognize/recognizer.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/oblique_rig.hpp"
#include "hw-sim/scene/random_scene.hpp"
#include "support/polyhedra_catalog.hpp"
#include "support/segment_by_cells.hpp"

namespace {

using fs::host::rec::RecognizeParams;
using fs::host::rec::Recognizer;

using Bench = fs::test::PolyhedraCatalog;
const Bench& bench() { return fs::test::polyhedra_catalog(); }
// The catalog of `bench_recognition --seed 1000` (its solids sized with seed 1000).
const Bench& bench_seed_1000() { return fs::test::polyhedra_catalog(1000); }

// The name of the model of r reported within 10 mm of scene object `index`'s centre ("" = none).
// The reported object whose model centre lies within `within_mm` of object `index`'s: its model, then its
// alternatives (empty when there is none).
std::vector<std::string> candidates_near(const fs::host::rec::Recognition& r, const fs::sim::RandomScene& rs,
                                         std::size_t index, const Bench& b, double within_mm = 10.0) {
  const auto& truth = b.library.models[static_cast<std::size_t>(rs.catalog_index.at(index))];
  const auto& obj = rs.scene.objects.at(index);
  const fs::Vec3 centre = obj.rotation * truth.center + obj.translation;
  std::vector<std::string> names;
  for (const auto& h : r.objects) {
    const auto& m = b.library.models[static_cast<std::size_t>(h.model)];
    if ((h.R * m.center + h.t - centre).norm() >= within_mm) continue;
    names.push_back(m.name);
    for (const auto& a : h.listed_alternatives())
      names.push_back(b.library.models[static_cast<std::size_t>(a.model)].name);
    break;
  }
  return names;
}

// Its model ("" when there is none).
std::string reported_near(const fs::host::rec::Recognition& r, const fs::sim::RandomScene& rs,
                          std::size_t index, const Bench& b, double within_mm = 10.0) {
  const auto names = candidates_near(r, rs, index, b, within_mm);
  return names.empty() ? std::string() : names.front();
}

// The same for the benchmark scene of `category`, `steps` and `seed`, recognized with `params`.
std::string recognized_at(fs::sim::SceneCategory category, std::uint32_t steps, std::uint64_t seed,
                          std::size_t index, const RecognizeParams& params, const Bench& b = bench()) {
  const auto rs = fs::sim::make_random_scene(b.catalog, {.category = category, .steps = steps}, seed);
  fs::host::OrganizedCloud cloud;
  fs::sim::make_ground_truth_grid(rs.scene, {.depth_noise_mm = 0.05, .seed = seed}).export_to(cloud, false);
  Recognizer rec(b.library, params, cloud.points.size());
  const fs::Plane table = rs.scene.calibration.table;
  const auto& r = rec.recognize(cloud, &table);
  return reported_near(r, rs, index, b);
}

std::size_t index_of(const fs::sim::RandomScene& rs, const std::string& name, const Bench& b = bench()) {
  for (std::size_t i = 0; i < rs.catalog_index.size(); ++i)
    if (rs.catalog_index[i] >= 0 &&
        b.library.models[static_cast<std::size_t>(rs.catalog_index[i])].name == name)
      return i;
  return rs.catalog_index.size();
}

// A cluttered scene of `bench_recognition --as-cloud --noise 0.08 --dropout 0.01 --sizes 55,85 --rig oblique
// --steps 240` (or `--rig bench --steps 250`; seed = 1 + its --only), its scan as a cloud of unknown origin
// (the recognizer finds the table), and the index of object `name` in it.
enum class Rig { oblique, bench };
struct CloudCase {
  CloudCase(std::uint64_t seed, const std::string& name, Rig rig = Rig::oblique)
      : rs(rig == Rig::oblique
               ? fs::sim::make_oblique_scene(
                     b.catalog, {.category = fs::sim::SceneCategory::cluttered, .steps = 240}, seed)
               : fs::sim::make_random_scene(
                     b.catalog, {.category = fs::sim::SceneCategory::cluttered, .steps = 250}, seed)),
        index(index_of(rs, name, b)) {
    fs::sim::make_ground_truth_grid(rs.scene, {.depth_noise_mm = 0.08, .seed = seed}).export_to(cloud, false);
    fs::sim::drop_points(cloud, 0.01, seed);
    cloud.scanner.reset();
  }
  bool found() const { return index < rs.catalog_index.size(); }
  // The report near the object with `params` (two threads): candidates_near.
  std::vector<std::string> candidates(RecognizeParams params, double within_mm = 10.0) const {
    params.threads = 2;
    Recognizer rec(b.library, params, cloud.points.size());
    return candidates_near(rec.recognize(cloud), rs, index, b, within_mm);
  }
  std::string reported(const RecognizeParams& params, double within_mm = 10.0) const {
    const auto names = candidates(params, within_mm);
    return names.empty() ? std::string() : names.front();
  }
  const Bench& b = fs::test::polyhedra_catalog(1, 55.0, 85.0);
  fs::sim::RandomScene rs;
  std::size_t index;
  fs::host::OrganizedCloud cloud;
};

// Seed 102 (separated, 250 steps): a triaugmented hexagonal prism, whose pyramids meet the squares at 5.3 deg
// creases. The laser default (0.3 mm) keeps them two faces; at 0.6 mm each pyramid's triangle and its square
// are one region, larger than the square beyond the area condition, so a triaugmented triangular prism was
// reported. Counting the square with its neighbours across shallow folds (match_area_fold_deg) matches the
// merged face to the square again.
TEST(RecognizeBenchmarkCases, FiveDegreeCreasesKeptOrMergedFindTheSolid) {
  const auto rs = fs::sim::make_random_scene(
      bench().catalog, {.category = fs::sim::SceneCategory::separated, .steps = 250}, 102);
  const std::size_t i = index_of(rs, "triaugmented-hexagonal-prism");
  ASSERT_LT(i, rs.catalog_index.size()) << "the benchmark scene changed";
  RecognizeParams params;
  params.threads = 2;
  EXPECT_EQ(recognized_at(fs::sim::SceneCategory::separated, 250, 102, i, params),
            "triaugmented-hexagonal-prism");
  params.segment.dist_abs_mm = 0.6;
  EXPECT_EQ(recognized_at(fs::sim::SceneCategory::separated, 250, 102, i, params),
            "triaugmented-hexagonal-prism");
  params.match_area_fold_deg = 0;
  EXPECT_EQ(recognized_at(fs::sim::SceneCategory::separated, 250, 102, i, params),
            "triaugmented-triangular-prism");
}

TEST(RecognizeBenchmarkCases, TheHypothesisExplainingMorePointsWinsATie) {
  const auto rs = fs::sim::make_random_scene(bench().catalog,
                                             {.category = fs::sim::SceneCategory::single, .steps = 500}, 89);
  ASSERT_EQ(index_of(rs, "parabiaugmented-hexagonal-prism"), 0u) << "the benchmark scene changed";
  RecognizeParams params;
  params.threads = 2;
  EXPECT_EQ(recognized_at(fs::sim::SceneCategory::single, 500, 89, 0, params),
            "parabiaugmented-hexagonal-prism");
  // With every 2nd row and column verified (the sampling of the version that failed) the two hypotheses tie
  // (confidence 0.998 both, 2367 vs 1889 inliers); the order without inlier_weight put the bare prism first.
  params.verify.sample_spacing_mm = 0.0;
  EXPECT_EQ(recognized_at(fs::sim::SceneCategory::single, 500, 89, 0, params),
            "parabiaugmented-hexagonal-prism");
  // Without inlier_weight and with t9.3's search cost (no area term) the order puts the bare prism first; the
  // replacement (the augmented prism explains its points and 25 % more) still reports the right model;
  // without both, the bare prism is reported. (With the area cost the search ranks the augmented prism
  // first.)
  params.inlier_weight = 0.0;
  params.area_cost = -1.0;
  EXPECT_EQ(recognized_at(fs::sim::SceneCategory::single, 500, 89, 0, params),
            "parabiaugmented-hexagonal-prism");
  params.replace_gain = 1e9;
  EXPECT_EQ(recognized_at(fs::sim::SceneCategory::single, 500, 89, 0, params), "hexagonal-prism");
}

// Seed 166 (separated, 500 steps): the metabiaugmented truncated dodecahedron shows only what the augmented
// one has too (same confidence 1.000, same 3036 inliers): whichever is reported must list the other as an
// alternative, and the JSON carries it.
TEST(RecognizeBenchmarkCases, LookAlikesAreListedAsAlternatives) {
  const Bench& b = bench();
  const auto rs = fs::sim::make_random_scene(
      b.catalog, {.category = fs::sim::SceneCategory::separated, .steps = 500}, 166);
  const std::size_t i = index_of(rs, "metabiaugmented-truncated-dodecahedron");
  ASSERT_LT(i, rs.catalog_index.size()) << "the benchmark scene changed";
  fs::host::OrganizedCloud cloud;
  fs::sim::make_ground_truth_grid(rs.scene, {.depth_noise_mm = 0.05, .seed = 166}).export_to(cloud, false);
  RecognizeParams params;
  params.threads = 2;
  Recognizer rec(b.library, params, cloud.points.size());
  const fs::Plane table = rs.scene.calibration.table;
  const auto& r = rec.recognize(cloud, &table);
  const auto& truth = b.library.models[static_cast<std::size_t>(rs.catalog_index[i])];
  const fs::Vec3 centre = rs.scene.objects[i].rotation * truth.center + rs.scene.objects[i].translation;
  const nlohmann::json j = fs::host::rec::to_json(r, b.library);
  bool seen = false;
  for (std::size_t k = 0; k < r.objects.size(); ++k) {
    const auto& h = r.objects[k];
    const auto& m = b.library.models[static_cast<std::size_t>(h.model)];
    if ((h.R * m.center + h.t - centre).norm() > 10.0) continue;
    seen = true;
    const std::string other = m.name == truth.name ? "augmented-truncated-dodecahedron" : truth.name;
    ASSERT_TRUE(j["objects"][k].contains("alternatives")) << j["objects"][k].dump();
    bool listed = false;
    for (const auto& a : j["objects"][k]["alternatives"]) listed = listed || a["model"] == other;
    EXPECT_TRUE(listed) << m.name << " does not list " << other << ": "
                        << j["objects"][k]["alternatives"].dump();
  }
  EXPECT_TRUE(seen);
  // Objects without a look-alike in view list none: the scene's other objects.
  int without = 0;
  for (const auto& o : j["objects"]) without += o.contains("alternatives") ? 0 : 1;
  EXPECT_GE(without, 1);
}

// The segmentation these 250-step cases were found with is by cells (fs::test::segment_by_cells). With the
// spans and thresholds that follow the sweep's spacing, the true model of several of them is reported without
// the rule each case pins as well; on these scenes as they were segmented then, only the rule gets there.
void segment_by_cells(RecognizeParams& p) { fs::test::segment_by_cells(p.segment); }

// A 250-step benchmark scene (catalog `b`), segmented by cells (or with the default segmentation): the model
// reported at object `name` with the default parameters, then with `change` applied to them.
enum class Segmentation { by_cells, defaults };
template <class Change>
std::pair<std::string, std::string> with_and_without(fs::sim::SceneCategory category, std::uint64_t seed,
                                                     const std::string& name, Change change,
                                                     const Bench& b = bench(),
                                                     Segmentation segmentation = Segmentation::by_cells) {
  const auto rs = fs::sim::make_random_scene(b.catalog, {.category = category, .steps = 250}, seed);
  const std::size_t i = index_of(rs, name, b);
  if (i >= rs.catalog_index.size()) return {"the benchmark scene changed", ""};
  RecognizeParams params;
  params.threads = 2;
  if (segmentation == Segmentation::by_cells) segment_by_cells(params);
  std::pair<std::string, std::string> out;
  out.first = recognized_at(category, 250, seed, i, params, b);
  change(params);
  out.second = recognized_at(category, 250, seed, i, params, b);
  return out;
}

// Seeds 53 (occluded) and 292 (separated), 250 steps: an augmented truncated dodecahedron shows its cupola
// and what the metabiaugmented one has too. Three hypotheses of the metabiaugmented model, placements that
// differ only in the second cupola out of view, tied the true model's best in the coarse check
// (confidence 1.000, 173 inliers) and came first, so they took all three refinements of the scene faces
// (refine_per_face) and the metabiaugmented one was reported with no alternative. A face's refinements now go
// to other models before copies of one (RecognizeParams::refine_models_first): the true model is refined and
// reported.
TEST(RecognizeBenchmarkCases, CopiesOfOnePlacementLeaveALookAlikeItsRefinement) {
  const std::pair<fs::sim::SceneCategory, std::uint64_t> cases[] = {{fs::sim::SceneCategory::occluded, 53},
                                                                    {fs::sim::SceneCategory::separated, 292}};
  for (const auto& [category, seed] : cases) {
    const auto atd = with_and_without(category, seed, "augmented-truncated-dodecahedron",
                                      [](RecognizeParams& p) { p.refine_models_first = false; });
    EXPECT_EQ(atd.first, "augmented-truncated-dodecahedron") << seed;
    EXPECT_EQ(atd.second, "metabiaugmented-truncated-dodecahedron") << seed;
  }
}

// Seed 460 (cluttered, 250 steps): a cube shows two faces, one partly hidden, so its coarse pose sits 3.8 mm
// off (confidence 0.645). Two placements of an augmented hexagonal prism (0.670, 0.663) and an augmented
// triangular prism (0.635) took the three refinements of those faces; the prism's refined fit passed (0.76)
// and was reported in the cube's place. A second placement of a model now waits for the other models'
// hypotheses down to refine_wait_margin lower (RecognizeParams::refine_models_first): the cube is refined
// (0.93) and reported. The wait ends there: in seed 1072 of `--seed 1000` (cluttered, 250 steps) the
// gyrobifastigium's second placement (0.661 against its first's 0.795) refines to the true pose (0.935); with
// no end to the wait, two prisms of 0.507 and 0.476 take its place and the gyrobifastigium is lost.
TEST(RecognizeBenchmarkCases, AnotherModelIsRefinedBeforeASecondPlacementOfOne) {
  constexpr auto kCluttered = fs::sim::SceneCategory::cluttered;
  const auto cube =
      with_and_without(kCluttered, 460, "cube", [](RecognizeParams& p) { p.refine_models_first = false; });
  EXPECT_EQ(cube.first, "cube");
  // (An augmented hexagonal prism before VerifyParams::slide_keep_inliers and table_snap_mm.)
  EXPECT_EQ(cube.second, "augmented-triangular-prism");
  const auto gyrobifastigium = with_and_without(
      kCluttered, 1072, "gyrobifastigium", [](RecognizeParams& p) { p.refine_wait_margin = 1.0; },
      bench_seed_1000());
  EXPECT_EQ(gyrobifastigium.first, "gyrobifastigium");
  EXPECT_EQ(gyrobifastigium.second, "");
}

// Seed 50 (cluttered, 250 steps): a dodecahedron, mostly hidden by its neighbours, shows three pentagons. Its
// one hypothesis sits on the true pose, but its prescore (0.22: the share of its predicted visible area that
// the matched faces explain) ranks it below the look-alikes that share pentagons; in the round after the
// first acceptance every face had verify_per_face better hypotheses, so it was never checked, though all of
// that round's hypotheses fit in max_verified. Now they are all checked (check_all_that_fit).
TEST(RecognizeBenchmarkCases, AllHypothesesAreCheckedWhenTheyFitTheBudget) {
  const auto dodecahedron = with_and_without(fs::sim::SceneCategory::cluttered, 50, "dodecahedron",
                                             [](RecognizeParams& p) { p.check_all_that_fit = false; });
  EXPECT_EQ(dodecahedron.first, "dodecahedron");
  EXPECT_EQ(dodecahedron.second, "");
}

// Seed 412 (separated, 250 steps): a triangular prism stands on a triangle and shows its top and one side.
// Their planes leave the translation along that side open; the matcher filled it from the face centroids, 1.7
// mm off, and the prism's hypothesis met 236 violations at its silhouette (confidence 0.51), so an augmented
// triangular prism (0.74) was reported. The refinement now slides such a pose along the open direction
// (verify_sliding).
TEST(RecognizeBenchmarkCases, ThePoseSlidesAlongTheDirectionItsPlanesLeaveOpen) {
  const auto rs = fs::sim::make_random_scene(
      bench().catalog, {.category = fs::sim::SceneCategory::separated, .steps = 250}, 412);
  const std::size_t i = index_of(rs, "triangular-prism");
  ASSERT_LT(i, rs.catalog_index.size()) << "the benchmark scene changed";
  RecognizeParams params;
  params.threads = 2;
  EXPECT_EQ(recognized_at(fs::sim::SceneCategory::separated, 250, 412, i, params), "triangular-prism");
  segment_by_cells(params);
  EXPECT_EQ(recognized_at(fs::sim::SceneCategory::separated, 250, 412, i, params), "triangular-prism");
  params.verify.slide_step_mm = 0.0;
  EXPECT_EQ(recognized_at(fs::sim::SceneCategory::separated, 250, 412, i, params),
            "augmented-triangular-prism");
}

// `bench_recognition --scenes 500 --steps 500 --only 434` and `--only 424` (cluttered): a search stops at its
// first solution, and the elongated pentagonal cupola's lay on the gyroelongated pentagonal cupola beside it,
// the truncated dodecahedron's on an augmented truncated dodecahedron. The true objects got no hypothesis of
// their models, and a decagonal prism and a triaugmented truncated dodecahedron took their faces. The second
// search of the part without the first solution's object (RecognizeParams::second_search) finds them.
TEST(RecognizeBenchmarkCases, ASecondSearchFindsTheModelWhoseFirstSolutionLayOnALookAlike) {
  const std::pair<std::uint64_t, std::pair<const char*, const char*>> cases[] = {
      {435, {"elongated-pentagonal-cupola", "decagonal-prism"}},
      {425, {"truncated-dodecahedron", "triaugmented-truncated-dodecahedron"}}};
  for (const auto& [seed, names] : cases) {
    const auto rs = fs::sim::make_random_scene(
        bench().catalog, {.category = fs::sim::SceneCategory::cluttered, .steps = 500}, seed);
    const std::size_t i = index_of(rs, names.first);
    ASSERT_LT(i, rs.catalog_index.size()) << "the benchmark scene changed";
    RecognizeParams params;
    params.threads = 2;
    EXPECT_EQ(recognized_at(fs::sim::SceneCategory::cluttered, 500, seed, i, params), names.first);
    // The placement check (RecognizeParams::placement) puts the first search's solutions on the neighbour
    // after the others, and of seed 435's cupola the true one then fits in the search's share of the pool
    // without a second search: off, to see what the second search does.
    params.placement.rms_mm = 0.0;
    EXPECT_EQ(recognized_at(fs::sim::SceneCategory::cluttered, 500, seed, i, params), names.first);
    params.second_search = false;
    EXPECT_EQ(recognized_at(fs::sim::SceneCategory::cluttered, 500, seed, i, params), names.second);
  }
}

// `bench_recognition --steps 250 --categories single --seed 1000 --only 11`: the augmented truncated
// tetrahedron stands on its cupola and shows two hexagons and a triangle of its body. The search placed the
// cupola on a hidden side instead, the body floating 17.6 mm above the table; the support test halved that
// hypothesis, and a bare truncated tetrahedron resting on the table (confidence 0.61, 229 violations) was
// reported. The placement on the cupola is a near symmetry that maps 49 % of the model's area onto itself:
// the reseat checks it since near_symmetry_share is 0.4 (it was 0.5).
TEST(RecognizeBenchmarkCases, AFloatingPlacementOfAnAugmentedSolidIsReseatedOntoTheTable) {
  const Bench& b = bench_seed_1000();
  const auto rs =
      fs::sim::make_random_scene(b.catalog, {.category = fs::sim::SceneCategory::single, .steps = 250}, 1011);
  ASSERT_EQ(index_of(rs, "augmented-truncated-tetrahedron", b), 0u) << "the benchmark scene changed";
  RecognizeParams params;
  params.threads = 2;
  EXPECT_EQ(recognized_at(fs::sim::SceneCategory::single, 250, 1011, 0, params, b),
            "augmented-truncated-tetrahedron");
  // Without the reseat the bare body is accepted first; the replacement by a better fit of the same points
  // (RecognizeParams::replace_better, or replace_violation_weight: the net count of points) then corrects it
  // in a later round. Without these, and without the space hidden under a solid holding it up, the body is
  // reported. (With that rule the floating placement holds: the column under its centre of mass is hidden by
  // its body, and the real cupola is there. It is reported 9.8 mm off the true centre, the cupola on a hidden
  // side: the reseat is what puts it right.)
  params.near_symmetry_share = 0.5;
  EXPECT_EQ(recognized_at(fs::sim::SceneCategory::single, 250, 1011, 0, params, b),
            "augmented-truncated-tetrahedron");
  params.replace_better = 2.0;
  params.replace_violation_weight = 0.0;
  params.support_hidden_below = false;
  // A search from one face per symmetry orbit (RecognizeParams::symmetry_roots) finds the placement on the
  // cupola itself; with the search from every face, the body is reported.
  EXPECT_EQ(recognized_at(fs::sim::SceneCategory::single, 250, 1011, 0, params, b),
            "augmented-truncated-tetrahedron");
  params.symmetry_roots = false;
  EXPECT_EQ(recognized_at(fs::sim::SceneCategory::single, 250, 1011, 0, params, b), "truncated-tetrahedron");
}

// `bench_recognition --steps 500 --categories cluttered --seed 1000 --only 174`: the augmented sphenocorona's
// hypothesis fits 0.998 in a placement that floats (support factor 0.5); its near-symmetric placement on the
// table fits 0.971 among its neighbours' points. The reseat scores a placement by fit x support, so it moves
// there and the object is found; scored by fit alone it stayed afloat, was not accepted, and a sphenocorona
// (its body) was reported in its place.
TEST(RecognizeBenchmarkCases, TheReseatPrefersThePlacementTheTableHoldsUp) {
  const Bench& b = bench_seed_1000();
  const auto rs = fs::sim::make_random_scene(
      b.catalog, {.category = fs::sim::SceneCategory::cluttered, .steps = 500}, 1174);
  const std::size_t i = index_of(rs, "augmented-sphenocorona", b);
  ASSERT_LT(i, rs.catalog_index.size()) << "the benchmark scene changed";
  RecognizeParams params;
  params.threads = 2;
  EXPECT_EQ(recognized_at(fs::sim::SceneCategory::cluttered, 500, 1174, i, params, b),
            "augmented-sphenocorona");
}

// `bench_recognition --rig oblique --steps 240 --as-cloud --noise 0.08 --dropout 0.01 --sizes 55,85
// --categories single,separated,occluded,cluttered --scenes 400 --only 171` (seed 172, cluttered): a
// gyroelongated pentagonal birotunda rests on a parabigyrate rhombicosidodecahedron that the laser, coming
// from behind, barely reaches (2 faces measured). The birotunda is seen on 16 faces and fits 0.95, but no
// measured point's ray passes the column under it: the support test asked for 3 rays ending in front of that
// space (RecognizeParams::hidden_below_min_rays), called the solid floating, and nothing was reported there.
TEST(RecognizeBenchmarkCases, ASolidOnASupportTheLaserCannotReachIsHeldUp) {
  const CloudCase c(172, "gyroelongated-pentagonal-birotunda");
  ASSERT_TRUE(c.found()) << "the benchmark scene changed";
  ASSERT_GE(c.rs.support[c.index], 0) << "the benchmark scene changed";
  RecognizeParams params;
  EXPECT_EQ(c.reported(params), "gyroelongated-pentagonal-birotunda");
  params.hidden_below_min_rays = 3;
  EXPECT_EQ(c.reported(params), "");
}

// Oblique rig, `--only 27` and `--only 155` of the command above (seeds 28 and 156, cluttered): a hexagonal
// prism lying on a side, seen on two faces in a pile, beside its augmented look-alikes (a square pyramid on a
// side face that is out of view).
// - Seed 28: the two seen faces are parallel to the prism's axis, so the pose slides along it. The 1 mm and
//   0.5 mm steps left it 0.23 mm off, where it explains 257 of the 274 points it explains in place (the
//   points at the ends of its faces move to the range tolerance's other side), and the metabiaugmented
//   hexagonal prism, placed better, was reported alone. The fine steps (VerifyParams::slide_fine_mm) put
//   the prism in place, and it is reported.
// - Seed 156: 225 points of the prism are measured. The metabiaugmented prism explains 63 fine samples, the
//   prism 60, both without a violation: 97 % of 63 asked for 61, and the report named the look-alike alone.
//   With 3 points of slack (RecognizeParams::alternative_inlier_slack) the prism is listed: "X or Y".
TEST(RecognizeBenchmarkCases, AnObjectSeenSmallIsPlacedFinelyAndItsLookAlikesListed) {
  const CloudCase first(28, "hexagonal-prism");
  ASSERT_TRUE(first.found()) << "the benchmark scene changed";
  RecognizeParams params;
  params.verify.slide_fine_mm = 0.0;
  const std::vector<std::string> placed_coarsely = first.candidates(params);
  ASSERT_FALSE(placed_coarsely.empty());
  EXPECT_EQ(placed_coarsely[0], "metabiaugmented-hexagonal-prism");
  EXPECT_EQ(std::ranges::count(placed_coarsely, "hexagonal-prism"), 0);
  EXPECT_EQ(first.reported(RecognizeParams{}), "hexagonal-prism");

  const CloudCase second(156, "hexagonal-prism");
  ASSERT_TRUE(second.found()) << "the benchmark scene changed";
  params = {};
  params.alternative_inlier_slack = 0;
  const std::vector<std::string> strict = second.candidates(params);
  ASSERT_FALSE(strict.empty());
  EXPECT_NE(strict[0], "hexagonal-prism");
  EXPECT_EQ(std::ranges::count(strict, "hexagonal-prism"), 0);
  EXPECT_EQ(std::ranges::count(second.candidates(RecognizeParams{}), "hexagonal-prism"), 1) << "listed";
}

// Oblique rig, `--only 207` (seed 208, cluttered): an octahedron rests on a truncated cuboctahedron the laser
// barely reaches, and shows its two upper faces. A square pyramid fits their upper part, its lowest corner 6
// mm above the octahedron's lowest point, and the support test found measured points under its lowest corner:
// the same two faces going on below it. It was reported (0.78). Points on its own seen faces' planes no
// longer hold it up (RecognizeParams::support_own_plane_mm), and nothing is reported there.
TEST(RecognizeBenchmarkCases, TheTopOfASolidIsNotHeldUpByTheSolidsOwnFaces) {
  const CloudCase c(208, "octahedron");
  ASSERT_TRUE(c.found()) << "the benchmark scene changed";
  RecognizeParams params;
  params.support_own_plane_mm = 0.0;
  EXPECT_EQ(c.reported(params, 20.0), "square-pyramid");  // within 20 mm of the octahedron's centre
  EXPECT_EQ(c.reported(RecognizeParams{}, 20.0), "");
}

// Oblique rig, `--only 247` (seed 248, cluttered): a triangular prism rests on a parabigyrate
// rhombicosidodecahedron, seen on 1 face, and not reported. The gyrate bidiminished rhombicosidodecahedron
// (two cupolae fewer, where the prism hides them) explains 152 fine samples, the true model 153, neither with
// a violation; but the prism ends 45 of the true model's rays in front of it and 25 of the look-alike's, so
// their confidences (0.932, 0.961) lay 0.029 apart and the look-alike was reported alone. Without the
// occluded rays (RecognizeParams::alternative_seen_fit) both fit 1.0, and the true model is listed.
TEST(RecognizeBenchmarkCases, WhatHidesTwoLookAlikesDoesNotTellThemApart) {
  const CloudCase c(248, "parabigyrate-rhombicosidodecahedron");
  ASSERT_TRUE(c.found()) << "the benchmark scene changed";
  RecognizeParams params;
  params.alternative_seen_fit = false;
  const std::vector<std::string> before = c.candidates(params);
  ASSERT_FALSE(before.empty());
  EXPECT_EQ(before[0], "gyrate-bidiminished-rhombicosidodecahedron");
  EXPECT_EQ(std::ranges::count(before, "parabigyrate-rhombicosidodecahedron"), 0);
  const std::vector<std::string> after = c.candidates(RecognizeParams{});
  EXPECT_EQ(std::ranges::count(after, "parabigyrate-rhombicosidodecahedron"), 1) << "listed";
}

// Bench rig, `--rig bench --steps 250 --only 311` (seed 312, cluttered): a tetrahedron on the table shows two
// faces, both partly hidden. Its hypothesis has the true rotation but sits 4 mm off along the two faces'
// common edge (placed by the faces' seen centroids), which climbs: its lowest corner floats 3.3 mm above the
// table, the support test halves it (0.45), and a truncated tetrahedron 14 mm away, seen through by 129 rays,
// was reported (0.69). Moved along that edge onto the table it fits as well and rests there
// (RecognizeParams::table_snap_mm).
TEST(RecognizeBenchmarkCases, ASolidFreeAlongAClimbingEdgeIsMovedOntoTheTable) {
  const CloudCase c(312, "tetrahedron", Rig::bench);
  ASSERT_TRUE(c.found()) << "the benchmark scene changed";
  RecognizeParams params;
  params.table_snap_mm = 0.0;
  EXPECT_EQ(c.reported(params, 20.0), "truncated-tetrahedron");
  EXPECT_EQ(c.reported(RecognizeParams{}), "tetrahedron");
}

// Bench rig, `--only 327` (seed 328, cluttered): a cube shows its top and a side, the top partly hidden. Its
// hypothesis slid 11 mm along their common edge explains 408 fine samples, 17 more than the true pose (a
// neighbour's points), while 141 rays see through it; the true pose explains 391 with none. The slide took
// only offsets that explain at least as many points, so the cube was reported 11 mm off (0.69). It now may
// give up 5 % of them (VerifyParams::slide_keep_inliers): the cube is placed right, and listed with an
// elongated square pyramid whose differences are out of view.
TEST(RecognizeBenchmarkCases, TheSlideGivesUpPointsForRaysThatSeeThroughTheSolid) {
  const CloudCase c(328, "cube", Rig::bench);
  ASSERT_TRUE(c.found()) << "the benchmark scene changed";
  RecognizeParams params;
  params.verify.slide_keep_inliers = 1.0;
  EXPECT_EQ(c.reported(params, 20.0), "cube");
  EXPECT_EQ(std::ranges::count(c.candidates(params), "cube"), 0) << "not within 10 mm";
  EXPECT_EQ(std::ranges::count(c.candidates(RecognizeParams{}), "cube"), 1);
}

// Seed 86 (cluttered, 250 steps): an elongated pentagonal rotunda, tilted on a neighbour, shows its decagon
// and a square. Region growing followed the 10.8 deg fold from the square into the triangle beside it: one
// scene face of 207 mm2 against the square's 134, beyond the area condition (1.3 x 134 + 30 = 204), so the
// search never paired them, no hypothesis of the rotunda existed, and a hexagonal prism was reported in its
// place (0.85). The condition now counts the square with its neighbours across folds of up to 15 deg
// (RecognizeParams::match_area_fold_deg).
TEST(RecognizeBenchmarkCases, AFaceGrownOverAShallowFoldStillMeetsItsModelFace) {
  const auto rotunda = with_and_without(
      fs::sim::SceneCategory::cluttered, 86, "elongated-pentagonal-rotunda",
      [](RecognizeParams& p) { p.match_area_fold_deg = 0; }, bench(), Segmentation::defaults);
  EXPECT_EQ(rotunda.first, "elongated-pentagonal-rotunda");
  EXPECT_EQ(rotunda.second, "hexagonal-prism");
}

// Seeds 80 and 18 (cluttered, 250 steps): a smaller model fitted part of a larger solid and was accepted
// first; the true model's hypothesis explained all its points and more, but missed both replacement rules by
// a hair.
// - Seed 80: an elongated pentagonal orthobirotunda (14 faces seen) against a triangular hebesphenorotunda
//   20 mm off (476 inliers and 5 violations against 421 and 0; confidence 0.954 against 0.975, lowered by 71
//   rays that its neighbours end in front of it).
// - Seed 18: a gyroelongated pentagonal cupola against a gyroelongated square cupola (301 inliers and 4
//   violations against 347 and 77).
// Counting a violation against two inliers, with the fit of the points in view, the true model replaces it
// (RecognizeParams::replace_violation_weight).
TEST(RecognizeBenchmarkCases, AViolationCountsAgainstTheInliersWhenOneModelReplacesAnother) {
  const std::pair<std::uint64_t, std::string> cases[] = {{80, "elongated-pentagonal-orthobirotunda"},
                                                         {18, "gyroelongated-pentagonal-cupola"}};
  const std::string before[] = {"", "gyroelongated-square-cupola"};
  for (std::size_t k = 0; k < 2; ++k) {
    const auto& [seed, name] = cases[k];
    const auto reported = with_and_without(
        fs::sim::SceneCategory::cluttered, seed, name,
        [](RecognizeParams& p) { p.replace_violation_weight = 0.0; }, bench(), Segmentation::defaults);
    EXPECT_EQ(reported.first, name) << "seed " << seed;
    EXPECT_EQ(reported.second, before[k]) << "seed " << seed;
  }
}

// Seeds 31 and 185 (cluttered, 250 steps): a pyramid lying on a side shows its base alone, which its
// neighbours partly hide.
// - Seed 31: a square pyramid's base, seen at 0.52 x its area (1025 of 1953 mm2), below the lone-face area
//   condition (0.7 x): no hypothesis of it existed and nothing was reported there. Larger model faces are now
//   placed on such a face too, by its centroid and by either end of its view
//   (RecognizeParams::single_face_hidden_min_area_ratio).
// - Seed 185: a pentagonal pyramid's base, seen at 0.4 x its area. Among those placements a pentagonal
//   rotunda fits the seen part (365 inliers, 9 violations, confidence 0.84), 13 mm from the pyramid; so
//   little of such an object is in view that it must fit clearly (single_face_hidden_min_confidence 0.9).
TEST(RecognizeBenchmarkCases, APartlyHiddenLoneFaceIsPlacedByTheEndOfItsView) {
  constexpr auto kCluttered = fs::sim::SceneCategory::cluttered;
  const auto square = with_and_without(
      kCluttered, 31, "square-pyramid", [](RecognizeParams& p) { p.single_face_hidden_min_area_ratio = 0.0; },
      bench(), Segmentation::defaults);
  EXPECT_EQ(square.first, "square-pyramid");
  EXPECT_EQ(square.second, "");

  const auto rs = fs::sim::make_random_scene(bench().catalog, {.category = kCluttered, .steps = 250}, 185);
  const std::size_t j = index_of(rs, "pentagonal-pyramid");
  ASSERT_LT(j, rs.catalog_index.size()) << "the benchmark scene changed";
  fs::host::OrganizedCloud cloud;
  fs::sim::make_ground_truth_grid(rs.scene, {.depth_noise_mm = 0.05, .seed = 185}).export_to(cloud, false);
  const fs::Plane table = rs.scene.calibration.table;
  auto near_pyramid = [&](const RecognizeParams& p) {
    Recognizer rec(bench().library, p, cloud.points.size());
    return reported_near(rec.recognize(cloud, &table), rs, j, bench(), 20.0);
  };
  RecognizeParams params;
  params.threads = 2;
  EXPECT_EQ(near_pyramid(params), "");
  params.single_face_hidden_min_confidence = params.min_confidence;
  EXPECT_EQ(near_pyramid(params), "pentagonal-rotunda");
}

// Seeds 49 and 40 (oblique rig, as clouds): a solid resting on another one that it hides shows only its top.
// - Seed 49: a pentagonal cupola upside down on a triaugmented dodecahedron of which no point is measured.
//   Its decagon (7,429 points) is a lone face 45 mm higher than the cupola stands: no model fits it on the
//   table. Raised placements (RecognizeParams::single_face_raised) put it on the hidden space under it.
// - Seed 40: a cube on a pentagonal orthobirotunda that shows two faces of 98 points.
TEST(RecognizeBenchmarkCases, ALoneTopRestsOnWhatItHides) {
  const std::pair<std::uint64_t, std::string> cases[] = {{49, "pentagonal-cupola"}, {40, "cube"}};
  for (const auto& [seed, name] : cases) {
    const CloudCase c(seed, name);
    ASSERT_TRUE(c.found()) << "the benchmark scene changed: seed " << seed;
    RecognizeParams params;
    EXPECT_EQ(c.reported(params), name) << "seed " << seed;
    params.single_face_raised = false;
    EXPECT_EQ(c.reported(params), "") << "seed " << seed;
  }
}

}  // namespace
