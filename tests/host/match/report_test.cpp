// Text (fig. 7.21 style) and JSON reports of a match, on the example files of tests/host/match/data.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "host/match/inexact.hpp"
#include "host/match/params.hpp"
#include "host/match/report.hpp"
#include "host/pfrg/pfrg.hpp"
#include "support/test_paths.hpp"

namespace {

using namespace fs::host::match;

TEST(Report, CornerExampleTextAndJson) {
  const auto dir = fs::test::source_dir() / "tests/host/match/data";
  const fs::host::Pfrg scene = fs::host::read_pfrg_json(dir / "corner_scene.json");
  const fs::host::Pfrg ref = fs::host::read_pfrg_json(dir / "cube_ref.json");
  EXPECT_EQ(scene.name, "corner");
  InexactMatcher m;
  const MatchResult& r = m.match(scene, ref, preset("t7.19"));
  ASSERT_GE(r.solutions.size(), 2u);
  // A cube corner has 24 equivalent matches (8 corners x 3 rotations).
  EXPECT_EQ(r.stats.solutions, 24);
  // The rotation fits of the level >= 2 states take the fast path; none is degenerate here.
  EXPECT_GT(r.stats.fits_fast, 0);
  EXPECT_EQ(r.stats.fits_fallback, 0);
  EXPECT_DOUBLE_EQ(r.stats.cost_ratio, 1.0);
  const std::string text = format_result(r, "corner", 2);
  EXPECT_NE(text.find("1 corner."), std::string::npos);
  EXPECT_NE(text.find("; nb of sce arcs inserted"), std::string::npos);
  EXPECT_NE(text.find("stopping condition                 : no states left"), std::string::npos);
  EXPECT_NE(text.find("removed by rigidity"), std::string::npos);
  const nlohmann::json j = result_json(r, "corner", 5);
  ASSERT_EQ(j["solutions"].size(), 5u);
  const auto& s0 = j["solutions"][0];
  EXPECT_EQ(s0["level"], 3);
  EXPECT_EQ(s0["arcs_inserted"], 1);
  EXPECT_EQ(s0["matches"].size(), 3u);
  EXPECT_EQ(s0["rotation"].size(), 3u);
  EXPECT_EQ(s0["id"].get<std::string>().rfind("corner.", 0), 0u);
  EXPECT_EQ(j["stats"]["stop"], "no states left");
  EXPECT_GT(j["stats"]["removed"]["rigidity"].get<int>(), 0);
  EXPECT_EQ(j["stats"]["solutions"], 24);
  // Rotation of solution 1 maps the reference normals onto the matched scene normals.
  const Solution& s = r.solutions[0];
  for (const auto& mm : s.matches)
    EXPECT_LT((s.rotation * ref.find(mm.ref)->normal - scene.find(mm.scene)->normal).norm(), 1e-6);
}

TEST(Report, NewMatchConditionPreventsDuplicateStates) {
  const auto dir = fs::test::source_dir() / "tests/host/match/data";
  const fs::host::Pfrg scene = fs::host::read_pfrg_json(dir / "corner_scene.json");
  const fs::host::Pfrg ref = fs::host::read_pfrg_json(dir / "cube_ref.json");
  InexactMatcher m;
  MatchParams p = preset("t7.19");
  const std::int64_t with = m.match(scene, ref, p).stats.states_created;
  p.set(Condition::kNewMatch, false);
  const MatchResult& r = m.match(scene, ref, p);
  EXPECT_GT(r.stats.states_created, with);  // the lattice instead of a tree
  EXPECT_EQ(r.stats.removed[static_cast<int>(Condition::kNewMatch)], 0);
  // Without the test the same match set is reached along several paths; identical sets are not proper
  // subsets, so such a leaf is listed once per path.
  EXPECT_GT(r.stats.solutions, 24);
}

}  // namespace
