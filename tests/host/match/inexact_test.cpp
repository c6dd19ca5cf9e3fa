// Inexact best-first matching (ch. 7) on hand-made graphs and rigid / perturbed partial views.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

#include <nlohmann/json.hpp>

#include "common/error.hpp"
#include "host/match/node_set.hpp"

#if FS_HAVE_ALLOC_COUNTER
#include "common/alloc_counter/alloc_counter.hpp"
#endif
#include "common/mesh.hpp"
#include "host/library/model.hpp"
#include "host/match/inexact.hpp"
#include "host/match/parallel.hpp"
#include "host/match/params.hpp"
#include "host/match/report.hpp"
#include "match_helpers.hpp"
#include "support/merged_faces.hpp"
#include "support/test_paths.hpp"
#include "test_graphs.hpp"

namespace {

using namespace fs::host::match;
using fs::Mat3;
using fs::Vec3;
using fs::host::Pfrg;

const Vec3 kViewDir(0, 0, -1);  // sensor on +z looking down

fs::Mesh johnson(const std::string& name) {
  return fs::read_mesh(fs::test::shared_data() / "polyhedra/polyhedra-viewer/off" / (name + ".off"));
}

// Random rotations whose view shows between 3 and 6 faces.
std::vector<Mat3> views_of(const Pfrg& model, int count, std::mt19937& rng) {
  std::vector<Mat3> out;
  for (int tries = 0; tries < 1000 && static_cast<int>(out.size()) < count; ++tries) {
    const Mat3 R = fs::test::random_rotation(rng);
    const Pfrg v = fs::test::rigid_view(model, R, kViewDir);
    const int n = static_cast<int>(fs::test::real_ids(v).size());
    if (n >= 3 && n <= 6) out.push_back(R);
  }
  return out;
}

TEST(Inexact, CornerWithMissingArc) {
  // Thesis 7.8.1 "CORNER": three faces of a corner, one arc missing in the scene; reference = the cube.
  const Pfrg cube = fs::test::mesh_pfrg(fs::test::box(100, 100, 100));
  std::mt19937 rng(5);
  const Mat3 R = fs::test::random_rotation(rng);
  Pfrg scene;
  scene.name = "corner";
  for (int id : {1, 3, 4}) {  // top, +x side, +y side (mutually adjacent)
    auto n = *cube.find(id);
    n.normal = R * n.normal;
    scene.nodes.push_back(n);
  }
  fs::host::PfrgNode sn;  // the rest of the scene (unknown regions)
  sn.id = 99;
  sn.supernode = true;
  scene.nodes.push_back(sn);
  scene.arcs = {{1, 3, 100}, {1, 4, 100}, {1, 99, 200}, {3, 99, 200}, {4, 99, 200}};  // 3-4 missing
  InexactMatcher m;
  const MatchResult& r = m.match(scene, cube, preset("t7.19"));
  ASSERT_GE(r.solutions.size(), 1u) << format_result(r, "corner");
  const Solution& s = r.solutions[0];
  EXPECT_EQ(s.level, 3);
  EXPECT_EQ(s.arcs_matched, 2);
  EXPECT_EQ(s.arcs_inserted, 1);
  EXPECT_EQ(s.arcs_deleted, 0);
  const auto v = fs::test::judge(cube, R, s);
  EXPECT_TRUE(v.equivalent);
  EXPECT_LT(v.rotation_error_deg, 0.1);
  // cost = (beta*0 + gamma*1 + delta*0) / 3 arcs
  EXPECT_NEAR(s.cost, 0.01 / 3, 1e-9);
  EXPECT_EQ(r.stats.stop, StopReason::kNoStates);
  EXPECT_EQ(state_id("corner", s.path).rfind("corner.", 0), 0u);
}

struct Case {
  std::string name;
  Pfrg model;
};

std::vector<Case> test_objects() {
  std::vector<Case> cases;
  cases.push_back({"cube", fs::test::mesh_pfrg(fs::test::box(100, 100, 100))});
  cases.push_back({"pyram2", fs::test::mesh_pfrg(fs::test::truncated_pyramid())});
  for (const char* j : {"square-pyramid", "pentagonal-pyramid", "triangular-cupola", "square-cupola",
                        "pentagonal-cupola", "elongated-triangular-pyramid", "elongated-square-pyramid",
                        "gyroelongated-square-pyramid", "triangular-bipyramid", "pentagonal-bipyramid"})
    cases.push_back({j, fs::test::mesh_pfrg(johnson(j), 50.0)});
  return cases;
}

TEST(Inexact, RigidViewsCorrectFirst) {
  std::mt19937 rng(11);
  InexactMatcher m;
  const MatchParams p = preset("t7.34");
  int checked = 0;
  for (const auto& c : test_objects()) {
    for (const Mat3& R : views_of(c.model, 3, rng)) {
      const Pfrg scene = fs::test::rigid_view(c.model, R, kViewDir);
      const MatchResult& r = m.match(scene, c.model, p);
      ASSERT_GE(r.solutions.size(), 1u) << c.name;
      const Solution& s = r.solutions[0];
      const auto v = fs::test::judge(c.model, R, s);
      EXPECT_TRUE(v.equivalent) << c.name << " wrong matches " << v.wrong_matches << "\n"
                                << format_result(r, c.name, 3);
      EXPECT_LT(v.rotation_error_deg, 0.1) << c.name;
      EXPECT_EQ(s.level, static_cast<int>(fs::test::real_ids(scene).size())) << c.name;
      EXPECT_TRUE(s.complete);
      ++checked;
    }
  }
  EXPECT_GE(checked, 30);
}

// Scan-like perturbations (normals +-3 deg, areas +-15 %, a split face, a spurious face, a missing arc).
// Runs the same perturbed views under a preset and returns how many have solution 1 correct (up to symmetry,
// rotation error < 5 deg); the names of the wrong ones and the cost ratios are appended to the strings.
struct PerturbedRun {
  int checked = 0, correct = 0;
  int correspondence =
      0;  // solution 1 has the right correspondence (up to symmetry), whatever its rotation error
  double max_rot_err = 0.0;  // over the views with the right correspondence first
  std::string wrong, ratios;
};
PerturbedRun run_perturbed(const MatchParams& p, unsigned seed) {
  std::mt19937 rng(seed);
  InexactMatcher m;
  PerturbedRun out;
  for (const auto& c : test_objects()) {
    const bool must = c.name == "cube" || c.name == "pyram2";
    for (const Mat3& R : views_of(c.model, 3, rng)) {
      Pfrg scene = fs::test::rigid_view(c.model, R, kViewDir);
      if (fs::test::real_ids(scene).size() < 4 && !must) continue;
      const int split = fs::test::perturb(scene, fs::test::Perturbation{}, rng);
      std::map<int, int> orig{{2000, split}, {2001, split}, {3000, -1}};
      const MatchResult& r = m.match(scene, c.model, p);
      ++out.checked;
      if (r.solutions.empty()) {
        out.wrong += c.name + "(none) ";
        continue;
      }
      const auto v = fs::test::judge(c.model, R, r.solutions[0], orig);
      if (v.equivalent) {
        ++out.correspondence;
        out.max_rot_err = std::max(out.max_rot_err, v.rotation_error_deg);
      }
      if (v.equivalent && v.rotation_error_deg < 5.0) {
        ++out.correct;
      } else {
        out.wrong += c.name + " ";
        EXPECT_FALSE(must) << p.name << " " << c.name << ": solution 1 not correct\n"
                           << format_result(r, c.name, 2);
      }
      out.ratios += c.name + "=" + std::to_string(r.stats.cost_ratio) + " ";
    }
  }
  return out;
}

// With the thesis ranking (t7.34: by cost, which is normalized per level), Johnson solids with congruent face
// configurations (cupolas: squares and triangles meeting at equal angles) often put a small wrong 3-face
// match of an ambiguous part of the view first once the split face raises the correct match's cost, or a
// wrong large match whose rotation fit is poor. A solution is correct when its correspondence is right up to
// the model's symmetry (match_helpers.hpp: judge) and its rotation within 5 deg of the truth. The `scan`
// preset (params.cpp: solutions ranked by cost + zeta * unexplained neighbour area, rotation-fit increments
// <= 0.005, TH_omega 10 deg from level-1 parents on) fixes most of them. Nine seeds of views: the cube and
// the truncated pyramid must always come out right; the share of correct first solutions is reported and
// bounded.
TEST(Inexact, PerturbedViewsCorrectFirst) {
  PerturbedRun thesis, scan;
  for (unsigned seed : {23u, 1u, 2u, 3u, 4u, 5u, 6u, 7u, 8u}) {
    const PerturbedRun t = run_perturbed(preset("t7.34"), seed);
    const PerturbedRun s = run_perturbed(preset("scan"), seed);
    EXPECT_EQ(s.checked, t.checked);
    thesis.checked += t.checked, thesis.correct += t.correct, thesis.wrong += t.wrong;
    scan.checked += s.checked, scan.correct += s.correct, scan.wrong += s.wrong;
    thesis.correspondence += t.correspondence, scan.correspondence += s.correspondence;
    thesis.max_rot_err = std::max(thesis.max_rot_err, t.max_rot_err);
    scan.max_rot_err = std::max(scan.max_rot_err, s.max_rot_err);
    if (seed == 23u) thesis.ratios = t.ratios;
  }
  std::printf(
      "perturbed views, t7.34: %d of %d correct first; wrong: %s\ncost ratio solution 2 / solution 1 "
      "(seed 23): %s\n",
      thesis.correct, thesis.checked, thesis.wrong.c_str(), thesis.ratios.c_str());
  std::printf("perturbed views, scan: %d of %d correct first; wrong: %s\n", scan.correct, scan.checked,
              scan.wrong.c_str());
  std::printf(
      "right correspondence first (any rotation error): t7.34 %d, scan %d of %d; largest rotation error "
      "then: t7.34 %.2f deg, scan %.2f deg\n",
      thesis.correspondence, scan.correspondence, scan.checked, thesis.max_rot_err, scan.max_rot_err);
  RecordProperty("cost_ratios", thesis.ratios);
  EXPECT_GE(thesis.checked, 200);
  EXPECT_GE(scan.correct * 100, scan.checked * 97) << "wrong first under scan: " << scan.wrong;  // >= 97 %
  EXPECT_GE(scan.correspondence * 100, scan.checked * 99);       // right correspondence first: >= 99 %
  EXPECT_GE(scan.correct - thesis.correct, thesis.checked / 5);  // the ranking fixes >= 20 % of the views
}

Pfrg pyram2_scene(std::mt19937& rng, Mat3& R) {
  const Pfrg model = fs::test::mesh_pfrg(fs::test::truncated_pyramid());
  // Looking at the top and four sides: the pyramid upright, tilted a little toward the sensor.
  R = Eigen::AngleAxisd(fs::test::deg2rad(20), Vec3(1, 0.3, 0).normalized()).toRotationMatrix();
  Pfrg scene = fs::test::rigid_view(model, R, kViewDir);
  fs::test::Perturbation pert;
  pert.split = false;
  fs::test::perturb(scene, pert, rng);
  scene.name = "pyram2";
  return scene;
}

TEST(Inexact, Pyram2AllAttributesSearchMuchSmallerThanNoOrientation) {
  std::mt19937 rng(8);
  Mat3 R;
  const Pfrg scene = pyram2_scene(rng, R);
  const Pfrg model = fs::test::mesh_pfrg(fs::test::truncated_pyramid());
  MatcherLimits lim;
  lim.max_states = 20000;
  InexactMatcher m(lim);
  MatchParams p28 = preset("t7.28");
  p28.max_states = 20000;
  const MatchStats s28 = m.match(scene, model, p28).stats;
  MatchParams p34 = preset("t7.34");
  const MatchResult& r34 = m.match(scene, model, p34);
  const MatchStats s34 = r34.stats;
  std::printf(
      "PYRAM2-like: t7.28 %lld states (%lld solutions, stop: %s), t7.34 %lld states (%lld solutions, "
      "stop: %s)\n",
      static_cast<long long>(s28.states_created), static_cast<long long>(s28.solutions),
      std::string(stop_name(s28.stop)).c_str(), static_cast<long long>(s34.states_created),
      static_cast<long long>(s34.solutions), std::string(stop_name(s34.stop)).c_str());
  EXPECT_GT(s28.states_created, 5 * s34.states_created);
  EXPECT_EQ(s28.removed[static_cast<int>(Condition::kRigidity)], 0);
  EXPECT_GT(s34.removed[static_cast<int>(Condition::kRigidity)], 0);
  ASSERT_FALSE(r34.solutions.empty());
  const auto v = fs::test::judge(model, R, r34.solutions[0], {{3000, -1}});
  EXPECT_TRUE(v.equivalent) << format_result(r34, "pyram2", 3);
}

TEST(Inexact, ConditionsAreCountedAndSwitchable) {
  const Pfrg model = fs::test::mesh_pfrg(fs::test::truncated_pyramid());
  std::mt19937 rng(4);
  Mat3 R;
  const Pfrg scene = pyram2_scene(rng, R);
  InexactMatcher m;
  MatchParams p = preset("t7.34");
  const MatchStats on = m.match(scene, model, p).stats;
  for (Condition c :
       {Condition::kConnectivity, Condition::kSupernode, Condition::kRigidity, Condition::kNewMatch})
    EXPECT_GT(on.removed[static_cast<int>(c)], 0) << condition_name(c);
  p.set(Condition::kRigidity, false);
  const MatchStats off = m.match(scene, model, p).stats;
  EXPECT_EQ(off.removed[static_cast<int>(Condition::kRigidity)], 0);
  EXPECT_GT(off.states_created, on.states_created);
  EXPECT_GT(off.removed[static_cast<int>(Condition::kNeighborMatch)], 0);
  // Search depth: TH_maxlevel = 2 keeps every state at level <= 2.
  MatchParams d = preset("t7.34");
  d.th_maxlevel = 2;
  d.th_minlevel = 2;
  const MatchResult& rd = m.match(scene, model, d);
  EXPECT_GT(rd.stats.removed[static_cast<int>(Condition::kSearchDepth)], 0);
  for (const auto& s : rd.solutions) EXPECT_LE(s.level, 2);
  // Node degree threshold 0 removes more than 2.
  MatchParams nd = preset("t7.34");
  nd.th_nodedegree = 0;
  EXPECT_GT(m.match(scene, model, nd).stats.removed[static_cast<int>(Condition::kNodeDegree)], 0);
}

TEST(Inexact, SolutionsOrderedMinLevelNoSubsets) {
  const Pfrg model = fs::test::mesh_pfrg(fs::test::truncated_pyramid());
  std::mt19937 rng(9);
  Mat3 R;
  const Pfrg scene = pyram2_scene(rng, R);
  MatcherLimits lim;
  lim.max_reported = 1000;
  InexactMatcher m(lim);
  const MatchResult& r = m.match(scene, model, preset("t7.34"));
  ASSERT_GE(r.solutions.size(), 2u);
  EXPECT_EQ(static_cast<std::int64_t>(r.solutions.size()), std::min<std::int64_t>(r.stats.solutions, 1000));
  for (std::size_t i = 0; i < r.solutions.size(); ++i) {
    const Solution& a = r.solutions[i];
    EXPECT_GE(a.level, 3);
    EXPECT_EQ(a.rank, static_cast<int>(i) + 1);
    EXPECT_EQ(a.matches.size(), static_cast<std::size_t>(a.level));
    if (i > 0) {
      EXPECT_LE(r.solutions[i - 1].cost, a.cost);
    }
    std::set<std::pair<int, int>> sa;
    for (auto x : a.matches) sa.insert({x.scene, x.ref});
    EXPECT_EQ(sa.size(), a.matches.size());
    for (std::size_t k = 0; k < r.solutions.size(); ++k) {
      if (k == i) continue;
      std::set<std::pair<int, int>> sb;
      for (auto x : r.solutions[k].matches) sb.insert({x.scene, x.ref});
      EXPECT_FALSE(std::includes(sb.begin(), sb.end(), sa.begin(), sa.end()))
          << "solution " << i + 1 << " is a subset of " << k + 1;
    }
  }
  EXPECT_NEAR(r.stats.cost_ratio, r.solutions[1].cost / r.solutions[0].cost, 1e-12);
  EXPECT_EQ(r.stats.best_state, r.solutions[0].state);
}

TEST(Inexact, StateBudgetIsAGlobalStopWithIncompleteSolutions) {
  const Pfrg model = fs::test::mesh_pfrg(fs::test::truncated_pyramid());
  std::mt19937 rng(9);
  Mat3 R;
  const Pfrg scene = pyram2_scene(rng, R);
  MatcherLimits lim;
  lim.max_states = 300;  // the pool itself is the budget
  InexactMatcher m(lim);
  MatchParams p = preset("t7.28");
  const MatchResult& r = m.match(scene, model, p);
  EXPECT_EQ(r.stats.stop, StopReason::kStateBudget);
  EXPECT_EQ(r.stats.states_created, 300);
  ASSERT_FALSE(r.solutions.empty()) << format_result(r, "pyram2");
  bool incomplete = false;
  for (const auto& s : r.solutions) incomplete |= !s.complete;
  EXPECT_TRUE(incomplete);
  // keep_partial also reports states below TH_minlevel, flagged partial.
  p.keep_partial = true;
  const MatchResult& rp = m.match(scene, model, p);
  bool partial = false;
  for (const auto& s : rp.solutions) partial |= s.partial;
  EXPECT_TRUE(partial || rp.stats.solutions > r.stats.solutions);
}

class FakeClock final : public MatchClock {
 public:
  mutable std::int64_t t = 0;
  std::int64_t now_ns() const override { return t += 1'000'000; }  // 1 ms per reading
};

TEST(Inexact, TimeBudgetWithInjectedClock) {
  const Pfrg model = fs::test::mesh_pfrg(fs::test::truncated_pyramid());
  std::mt19937 rng(9);
  Mat3 R;
  const Pfrg scene = pyram2_scene(rng, R);
  FakeClock clock;
  InexactMatcher m;
  m.set_clock(&clock);
  MatchParams p = preset("t7.28");
  p.max_time_ms = 3;
  const MatchResult& r = m.match(scene, model, p);
  EXPECT_EQ(r.stats.stop, StopReason::kTimeBudget);
  EXPECT_LT(r.stats.states_expanded, 100);
}

TEST(Inexact, SolutionsFoundStop) {
  const Pfrg model = fs::test::mesh_pfrg(fs::test::truncated_pyramid());
  std::mt19937 rng(9);
  Mat3 R;
  const Pfrg scene = pyram2_scene(rng, R);
  InexactMatcher m;
  MatchParams p = preset("t7.34");
  p.max_solutions = 1;
  const MatchResult& r = m.match(scene, model, p);
  EXPECT_EQ(r.stats.stop, StopReason::kSolutionsFound);
  ASSERT_GE(r.solutions.size(), 1u);
  EXPECT_TRUE(fs::test::judge(model, R, r.solutions[0], {{3000, -1}}).equivalent);
}

TEST(Inexact, LevelOneSolutionsAreDegenerate) {
  const Pfrg model = fs::test::mesh_pfrg(fs::test::box(100, 50, 20));
  std::mt19937 rng(2);
  const Pfrg scene = fs::test::rigid_view(model, fs::test::random_rotation(rng), kViewDir);
  InexactMatcher m;
  MatchParams p = preset("t7.34");
  p.th_maxlevel = 1;
  p.th_minlevel = 1;
  const MatchResult& r = m.match(scene, model, p);
  ASSERT_FALSE(r.solutions.empty());
  for (const auto& s : r.solutions) {
    EXPECT_EQ(s.level, 1);
    EXPECT_TRUE(s.degenerate);
  }
}

TEST(Inexact, NoHeapAllocationDuringMatch) {
  std::mt19937 rng(31);
  const Pfrg model = fs::test::mesh_pfrg(fs::test::truncated_pyramid());
  Mat3 R;
  const Pfrg scene = pyram2_scene(rng, R);
  const Pfrg cube = fs::test::mesh_pfrg(fs::test::box(80, 80, 80));
  MatcherLimits lim;
  lim.max_states = 3000;
  InexactMatcher m(lim);
  MatchParams p = preset("t7.34");
  MatchParams p28 = preset("t7.28");  // runs into the pool limit
  (void)m.match(scene, model, p);     // warm-up (nothing to warm, but the rule is "after warm-up")
#if FS_HAVE_ALLOC_COUNTER
  fs::AllocCounter counter;
#endif
  std::int64_t total = 0;
  total += m.match(scene, model, p).stats.states_created;
  total += m.match(scene, cube, p).stats.states_created;
  const auto& r28 = m.match(scene, model, p28);
  total += r28.stats.states_created;
#if FS_HAVE_ALLOC_COUNTER
  EXPECT_EQ(counter.allocations(), 0u);
#else
  GTEST_SKIP() << "fs_alloc_counter not available";
#endif
  EXPECT_EQ(r28.stats.stop, StopReason::kStateBudget);
  EXPECT_GT(total, 0);
}

TEST(Inexact, ParallelDeterministicRegardlessOfThreads) {
  std::mt19937 rng(77);
  std::vector<Pfrg> refs;
  for (const auto& c : test_objects()) refs.push_back(c.model);
  Mat3 R;
  const Pfrg scene = pyram2_scene(rng, R);
  const MatchParams p = preset("t7.34");
  ParallelMatcher one(1), three(3);
  const auto a = one.match(scene, refs, p);
  const auto b = three.match(scene, refs, p);
  ASSERT_EQ(a.size(), refs.size());
  ASSERT_EQ(b.size(), refs.size());
  for (std::size_t i = 0; i < refs.size(); ++i) {
    EXPECT_EQ(a[i].stats.states_created, b[i].stats.states_created);
    ASSERT_EQ(a[i].solutions.size(), b[i].solutions.size());
    for (std::size_t k = 0; k < a[i].solutions.size(); ++k) {
      EXPECT_EQ(a[i].solutions[k].matches, b[i].solutions[k].matches);
      EXPECT_EQ(a[i].solutions[k].cost, b[i].solutions[k].cost);
      EXPECT_EQ(a[i].solutions[k].path, b[i].solutions[k].path);
    }
  }
  // The truncated pyramid (index 1) explains its own view best.
  double best = 1e300;
  std::size_t best_i = 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (!a[i].solutions.empty() && a[i].solutions[0].level >= 4 && a[i].solutions[0].cost < best) {
      best = a[i].solutions[0].cost;
      best_i = i;
    }
  EXPECT_EQ(best_i, 1u);
}

TEST(Inexact, OversizedGraphIsAnError) {
  Pfrg big;
  big.name = "big";
  for (int i = 0; i < kMaxNodes + 1; ++i) {
    fs::host::PfrgNode n;
    n.id = i;
    n.area = 1;
    n.normal = Vec3::UnitZ();
    big.nodes.push_back(n);
  }
  InexactMatcher m;
  EXPECT_THROW(m.match(big, big, preset("t7.34")), fs::Error);
}

TEST(Params, PresetsAndJson) {
  EXPECT_EQ(preset("t7.41").beta, 0.1);
  EXPECT_EQ(preset("t7.41").th_nodedegree, 6);
  EXPECT_EQ(preset("t9.3").epsilon, 0.8);
  EXPECT_EQ(preset("t7.28").epsilon, 0.0);
  EXPECT_TRUE(std::isinf(preset("t7.19").th_rotfit));
  EXPECT_EQ(preset("t7.30").alpha, 0.0);
  EXPECT_THROW(preset("nope"), fs::Error);
  const MatchParams p = params_from_json(
      nlohmann::json::parse(
          R"({"preset":"t7.41","alpha":0.2,"th_maxlevel":4,"conditions":{"rigidity":false}})"),
      "p");
  EXPECT_EQ(p.alpha, 0.2);
  EXPECT_EQ(p.beta, 0.1);
  EXPECT_EQ(p.th_maxlevel, 4);
  EXPECT_FALSE(p.on(Condition::kRigidity));
  const MatchParams back = params_from_json(to_json(p), "rt");
  EXPECT_EQ(back.enabled, p.enabled);
  EXPECT_EQ(back.th_cost, p.th_cost);
  EXPECT_TRUE(std::isinf(back.th_rotfit) == std::isinf(p.th_rotfit));
  // The scan preset's beyond-the-thesis switches round-trip as well.
  const MatchParams scan = preset("scan");
  const MatchParams scan_back = params_from_json(to_json(scan), "rt");
  EXPECT_EQ(scan_back.zeta, scan.zeta);
  EXPECT_TRUE(scan_back.rigidity_pairs);
  EXPECT_EQ(scan_back.th_area_ratio, 1.3);
  EXPECT_EQ(scan_back.th_area_fold_deg, 15.0);
  EXPECT_EQ(scan_back.max_states, 10000);
  EXPECT_THROW(params_from_json(nlohmann::json::parse(R"({"rigidity_pairs":1})"), "p"), fs::Error);
  EXPECT_THROW(params_from_json(nlohmann::json::parse(R"({"alfa":1})"), "p"), fs::Error);
  EXPECT_THROW(params_from_json(nlohmann::json::parse(R"({"conditions":{"x":true}})"), "p"), fs::Error);
  EXPECT_THROW(params_from_json(nlohmann::json::parse(R"({"alpha":-1})"), "p"), fs::Error);
  // The fold the area condition counts stays within the arc index's (match::kAreaFoldMaxDeg).
  EXPECT_EQ(params_from_json(nlohmann::json::parse(R"({"th_area_fold_deg":20})"), "p").th_area_fold_deg,
            20.0);
  EXPECT_THROW(params_from_json(nlohmann::json::parse(R"({"th_area_fold_deg":21})"), "p"), fs::Error);
  EXPECT_THROW(params_from_json(nlohmann::json::parse(R"({"th_area_fold_deg":-1})"), "p"), fs::Error);
}

}  // namespace

namespace {

// The one-sided area condition (th_area_ratio, beyond the thesis): a view whose faces are all twice the
// reference's can only come from a larger object: with the condition every pair is removed (counted under
// node similarity) and nothing matches; the reference's own view (scene areas <= reference areas) still
// matches exactly as without it.
TEST(Inexact, AreaRatioConditionRemovesScenesLargerThanTheReference) {
  const Pfrg model = fs::test::mesh_pfrg(fs::test::truncated_pyramid());
  const Mat3 R = Mat3::Identity();
  const Pfrg own = fs::test::rigid_view(model, R, kViewDir);
  Pfrg larger = own;
  for (auto& n : larger.nodes)
    if (!n.supernode) n.area *= 2.0;
  InexactMatcher m;
  MatchParams p = preset("t9.3");
  const auto base = m.match(own, model, p).solutions.size();
  ASSERT_GE(base, 1u);
  ASSERT_GE(m.match(larger, model, p).solutions.size(), 1u);  // without the condition areas do not matter

  p.th_area_ratio = 1.3;
  p.th_area_slack_mm2 = 30.0;
  const MatchResult& r_own = m.match(own, model, p);
  EXPECT_EQ(r_own.solutions.size(), base);
  EXPECT_EQ(r_own.stats.removed[static_cast<std::size_t>(Condition::kNodeSimilarity)], 0);
  const MatchResult& r_big = m.match(larger, model, p);
  EXPECT_EQ(r_big.solutions.size(), 0u);
  EXPECT_GT(r_big.stats.removed[static_cast<std::size_t>(Condition::kNodeSimilarity)], 0);
  // Switching node similarity off switches the area part off too.
  p.enabled[static_cast<std::size_t>(Condition::kNodeSimilarity)] = false;
  EXPECT_GE(m.match(larger, model, p).solutions.size(), 1u);
  // It round-trips through the parameter JSON.
  const MatchParams q = params_from_json(nlohmann::json{{"preset", "t9.3"}, {"th_area_ratio", 1.25}}, "test");
  EXPECT_DOUBLE_EQ(q.th_area_ratio, 1.25);
}

// A flat truncated pyramid (sides 9.9 deg off the top) seen from above, segmented as region growing does
// across such a shallow fold: the top and one side are one scene face, larger than the model's top by more
// than the area condition allows. With th_area_fold_deg the condition compares with the top plus its
// neighbours across the fold, and the top is matched again.
TEST(Inexact, AFaceGrownOverAShallowFoldKeepsItsReferenceFace) {
  const Pfrg model = fs::test::mesh_pfrg(fs::test::truncated_pyramid(100, 60, 3.5));
  const Pfrg view = fs::test::rigid_view(model, Mat3::Identity(), kViewDir);
  const Pfrg merged = fs::test::merged_faces(view, 1, 2);  // the top (node 1) grown over side 2
  ASSERT_EQ(merged.nodes.size(), view.nodes.size() - 1);
  InexactMatcher m;
  MatchParams p = preset("t9.3");
  p.th_area_ratio = 1.3;
  p.th_area_slack_mm2 = 30.0;
  auto top_on_top = [&](const MatchResult& r) {
    for (const auto& s : r.solutions)
      for (const auto& nm : s.matches)
        if (nm.scene == 1 && nm.ref == 1) return true;
    return false;
  };
  const MatchResult& without = m.match(merged, model, p);
  EXPECT_FALSE(top_on_top(without));
  EXPECT_GT(without.stats.removed[static_cast<std::size_t>(Condition::kNodeSimilarity)], 0);
  p.th_area_fold_deg = 15.0;
  EXPECT_TRUE(top_on_top(m.match(merged, model, p)));
  p.th_area_fold_deg = 9.0;  // the fold is 9.9 deg: not counted
  EXPECT_FALSE(top_on_top(m.match(merged, model, p)));
}

}  // namespace

namespace {

// Solution ranking by cost + zeta * U (beyond the thesis). U of a solution = area of the unmatched real scene
// faces adjacent to its matched faces / (that + matched area). The cube's corner view with one extra face
// attached to the top (an occluder's face): the complete corner solution leaves that face unexplained, so U
// is its share of the area; the search, the state count and the costs do not depend on zeta, only the order
// does.
TEST(Inexact, UnexplainedNeighbourAreaRanksSolutions) {
  const Pfrg cube = fs::test::mesh_pfrg(fs::test::box(100, 100, 100));
  Pfrg scene;
  scene.name = "corner+1";
  for (int id : {1, 3, 4}) scene.nodes.push_back(*cube.find(id));  // top, +x, +y: areas 10000
  fs::host::PfrgNode extra;
  extra.id = 7;
  extra.area = 2500.0;
  extra.normal = Vec3(0, 0, 1);  // parallel to the top: no cube face can take it next to the corner
  scene.nodes.push_back(extra);
  fs::host::PfrgNode sn;
  sn.id = 99;
  sn.supernode = true;
  scene.nodes.push_back(sn);
  scene.arcs = {{1, 3, 100},  {1, 4, 100},  {3, 4, 100},  {1, 7, 50},
                {1, 99, 200}, {3, 99, 200}, {4, 99, 200}, {7, 99, 100}};
  InexactMatcher m;
  MatchParams p = preset("t7.34");
  const MatchResult& r0 = m.match(scene, cube, p);
  ASSERT_FALSE(r0.solutions.empty());
  const std::int64_t states = r0.stats.states_created;
  const Solution s0 = r0.solutions[0];
  EXPECT_EQ(s0.level, 3);
  EXPECT_NEAR(s0.unexplained, 2500.0 / (2500.0 + 30000.0), 1e-12);
  const double cost0 = s0.cost;
  p.zeta = 0.5;
  const MatchResult& r1 = m.match(scene, cube, p);
  EXPECT_EQ(r1.stats.states_created, states);
  ASSERT_FALSE(r1.solutions.empty());
  EXPECT_DOUBLE_EQ(r1.solutions[0].cost, cost0);
  // Ranked by the key: non-decreasing cost + zeta U.
  for (std::size_t k = 1; k < r1.solutions.size(); ++k)
    EXPECT_LE(r1.solutions[k - 1].cost + p.zeta * r1.solutions[k - 1].unexplained,
              r1.solutions[k].cost + p.zeta * r1.solutions[k].unexplained + 1e-15);
  const MatchParams q = params_from_json(nlohmann::json{{"preset", "t7.34"}, {"zeta", 0.25}}, "test");
  EXPECT_DOUBLE_EQ(q.zeta, 0.25);
  EXPECT_DOUBLE_EQ(preset("scan").zeta, 0.1);
  EXPECT_THROW(params_from_json(nlohmann::json{{"zeta", -1}}, "test"), fs::Error);
}

// A reference with rotation symmetries searched only from one face per orbit (face_orbit_representatives)
// finds the poses of the search from every face: each pose of a complete solution of the most faces (a
// rotation equal up to a symmetry, the same scene faces) is among the other search's, and the search creates
// fewer states. The first solution is the true correspondence.
TEST(Inexact, ASearchFromOneFacePerSymmetryOrbitFindsTheSamePosesInFewerStates) {
  using Pose = std::pair<Mat3, std::set<int>>;
  auto poses = [](const MatchResult& r, int level) {
    std::vector<Pose> out;
    for (const Solution& s : r.solutions) {
      if (!s.complete || s.level != level) continue;
      std::set<int> faces;
      for (const NodeMatch& nm : s.matches) faces.insert(nm.scene);
      out.emplace_back(s.rotation, faces);
    }
    return out;
  };
  auto contains = [](const std::vector<Pose>& in, const Pose& p, const std::vector<Mat3>& group) {
    for (const Pose& q : in) {
      if (q.second != p.second) continue;
      for (const Mat3& S : group)
        if ((q.first - p.first * S).norm() < 1e-6) return true;
    }
    return false;
  };
  MatcherLimits limits;
  limits.max_reported = 4096;
  InexactMatcher m(limits);
  const MatchParams p = preset("t7.34");
  std::mt19937 rng(17);
  int views = 0;
  for (const char* name : {"truncated-cube", "truncated-tetrahedron", "square-cupola", "cuboctahedron"}) {
    fs::host::BuildOptions bo;
    bo.scale = 50.0;
    const fs::host::Model model = fs::host::build_model(johnson(name), bo);
    ASSERT_GT(model.symmetry_order(), 1u) << name;
    const std::vector<int> rep = fs::host::face_orbit_representatives(model);
    NodeSet first;
    for (std::size_t f = 0; f < rep.size(); ++f)
      if (rep[f] == static_cast<int>(f)) first.set(static_cast<int>(f));
    EXPECT_LT(first.count(), static_cast<int>(model.face_count())) << name;
    for (const Mat3& R : views_of(model.graph, 2, rng)) {
      const Pfrg scene = fs::test::rigid_view(model.graph, R, kViewDir);
      const int level = static_cast<int>(fs::test::real_ids(scene).size());
      const MatchResult& all_r = m.match(scene, model.graph, p);
      ASSERT_EQ(all_r.stats.stop, StopReason::kNoStates) << name;
      const std::int64_t all_states = all_r.stats.states_created;
      const std::vector<Pose> all = poses(all_r, level);
      SearchScope scope = full_scope();
      scope.first_refs = first;
      const MatchResult& one_r = m.match(scene, model.graph, p, scope);
      ASSERT_EQ(one_r.stats.stop, StopReason::kNoStates) << name;
      ASSERT_FALSE(one_r.solutions.empty()) << name;
      const auto v = fs::test::judge(model.graph, R, one_r.solutions[0]);
      EXPECT_TRUE(v.equivalent) << name;
      EXPECT_LT(v.rotation_error_deg, 0.1) << name;
      EXPECT_LT(one_r.stats.states_created, all_states) << name;
      const std::vector<Pose> one = poses(one_r, level);
      ASSERT_FALSE(one.empty()) << name;
      for (const Pose& q : all) EXPECT_TRUE(contains(one, q, model.symmetries)) << name;
      for (const Pose& q : one) EXPECT_TRUE(contains(all, q, model.symmetries)) << name;
      ++views;
    }
  }
  EXPECT_GE(views, 6);
}

// A scope's scene set: the faces outside it are never matched, and the search finds the solution of the rest.
TEST(Inexact, AScopeWithoutSomeSceneFacesMatchesOnlyTheOthers) {
  const Pfrg cube = fs::test::mesh_pfrg(fs::test::box(100, 100, 100));
  std::mt19937 rng(29);
  InexactMatcher m;
  MatchParams p = preset("t7.34");
  p.th_minlevel = 2;
  int checked = 0;
  for (const Mat3& R : views_of(cube, 4, rng)) {
    const Pfrg scene = fs::test::rigid_view(cube, R, kViewDir);
    const std::vector<int> real = fs::test::real_ids(scene);
    if (real.size() != 3) continue;
    SearchScope scope = full_scope();
    int dropped_index = -1;
    for (std::size_t i = 0; i < scene.nodes.size(); ++i)
      if (scene.nodes[i].id == real[0]) dropped_index = static_cast<int>(i);
    ASSERT_GE(dropped_index, 0);
    scope.scene.reset(dropped_index);
    const MatchResult& r = m.match(scene, cube, p, scope);
    ASSERT_FALSE(r.solutions.empty());
    EXPECT_EQ(r.solutions[0].level, 2);  // the other two faces of the corner
    for (const Solution& s : r.solutions)
      for (const NodeMatch& nm : s.matches) EXPECT_NE(nm.scene, real[0]);
    EXPECT_EQ(m.match(scene, cube, p).solutions[0].level, 3);
    ++checked;
  }
  EXPECT_GE(checked, 1);
}

}  // namespace
