// match::ArcIndex against the matcher it stands for: every reference with a search solution is a candidate
// (the index is exact), it rules most references out, and recognition gives the same answer with it.
#include <gtest/gtest.h>

#include <vector>

#include "host/library/library.hpp"
#include "host/library/model.hpp"
#include "host/match/arc_index.hpp"
#include "host/match/inexact.hpp"
#include "host/match/node_set.hpp"
#include "host/recognize/recognizer.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/random_scene.hpp"
#include "support/test_paths.hpp"

namespace {

using fs::host::rec::RecognizeParams;
using fs::host::rec::Recognizer;
using fs::sim::SceneCategory;

struct Bench {
  std::vector<fs::sim::CatalogEntry> catalog;
  fs::host::Library library;
};

const Bench& bench() {
  static const Bench b = [] {
    Bench x;
    x.catalog = fs::sim::make_catalog(
        fs::sim::read_catalog_meshes(fs::test::shared_data() / "polyhedra/polyhedra-viewer/off"),
        {.seed = 1});
    for (const auto& e : x.catalog) x.library.add(fs::host::build_model(e.mesh));
    return x;
  }();
  return b;
}

struct Scan {
  fs::host::OrganizedCloud cloud;
  fs::Plane table;
};

Scan scan_of(SceneCategory category, std::uint64_t seed) {
  const auto rs = fs::sim::make_random_scene(bench().catalog, {.category = category, .steps = 250}, seed);
  Scan s;
  fs::sim::make_ground_truth_grid(rs.scene, {.depth_noise_mm = 0.05, .seed = seed}).export_to(s.cloud, false);
  s.table = rs.scene.calibration.table;
  return s;
}

// The recognizer's first-round match parameters (host/recognize/prepare.cpp).
fs::host::match::MatchParams first_round(const RecognizeParams& rp) {
  fs::host::match::MatchParams p = rp.match;
  p.max_states = std::min<std::int64_t>(p.max_states, rp.max_states);
  p.th_minlevel = rp.min_level;
  p.max_solutions = rp.max_solutions;
  p.rigidity_pairs = rp.rigidity_pairs;
  p.th_omega_deg = rp.rigidity_deg;
  p.th_area_ratio = rp.match_area_ratio;
  p.th_area_slack_mm2 = rp.match_area_slack_mm2;
  return p;
}

TEST(ArcIndex, EveryReferenceWithASolutionIsACandidate) {
  const auto& lib = bench().library;
  std::vector<const fs::host::Pfrg*> graphs;
  for (const auto& m : lib.models) graphs.push_back(&m.graph);
  const fs::host::match::ArcIndex index(graphs);
  EXPECT_GT(index.entries(), lib.models.size());
  RecognizeParams rp;
  rp.threads = 2;
  const fs::host::match::MatchParams p = first_round(rp);
  ASSERT_TRUE(fs::host::match::ArcIndex::applies(p));
  fs::host::match::InexactMatcher matcher;
  int with_solution = 0, skipped = 0, checked = 0;
  for (auto [category, seed] : {std::pair{SceneCategory::single, 3},
                                {SceneCategory::separated, 5},
                                {SceneCategory::occluded, 7},
                                {SceneCategory::cluttered, 11},
                                {SceneCategory::cluttered, 12}}) {
    const Scan s = scan_of(category, static_cast<std::uint64_t>(seed));
    Recognizer rec(lib, rp, s.cloud.points.size());
    rec.recognize(s.cloud, &s.table);
    const fs::host::Pfrg& scene = rec.scene_graph();
    if (scene.nodes.size() > static_cast<std::size_t>(fs::host::match::kMaxNodes)) continue;
    std::vector<std::uint64_t> mark(lib.models.size(), 0);
    index.candidates(scene, p, mark, 1);
    for (std::size_t k = 0; k < lib.models.size(); ++k) {
      const auto& r = matcher.match(scene, lib.models[k].graph, p);
      bool solved = false;
      for (const auto& sol : r.solutions) solved = solved || !sol.partial;
      ++checked;
      with_solution += solved;
      skipped += mark[k] == 0;
      EXPECT_TRUE(!solved || mark[k] != 0)
          << lib.models[k].name << " has a solution but was ruled out, seed " << seed;
    }
  }
  // Not vacuous: solutions exist, and references are ruled out (on these whole multi-object graphs 86 of the
  // 600 pairs; a part of one object rules out more).
  EXPECT_GT(with_solution, 5);
  EXPECT_GT(skipped, checked / 10) << skipped << " of " << checked;
}

TEST(ArcIndex, RecognitionIsTheSameWithAndWithoutIt) {
  const auto& lib = bench().library;
  for (auto [category, seed] : {std::pair{SceneCategory::occluded, 21}, {SceneCategory::cluttered, 1011}}) {
    const Scan s = scan_of(category, static_cast<std::uint64_t>(seed));
    RecognizeParams with, without;
    with.threads = without.threads = 2;
    without.arc_index = false;
    Recognizer a(lib, with, s.cloud.points.size());
    Recognizer b(lib, without, s.cloud.points.size());
    const auto& ra = a.recognize(s.cloud, &s.table);
    const auto& rb = b.recognize(s.cloud, &s.table);
    EXPECT_EQ(ra.stats.solutions, rb.stats.solutions) << seed;
    EXPECT_EQ(ra.stats.hypotheses, rb.stats.hypotheses) << seed;
    EXPECT_LT(ra.stats.references_searched, rb.stats.references_searched) << seed;
    EXPECT_LT(ra.stats.states, rb.stats.states) << seed;
    ASSERT_EQ(ra.objects.size(), rb.objects.size()) << seed;
    ASSERT_FALSE(ra.objects.empty()) << seed;
    for (std::size_t i = 0; i < ra.objects.size(); ++i) {
      EXPECT_EQ(ra.objects[i].model, rb.objects[i].model) << seed;
      EXPECT_TRUE(ra.objects[i].R.isApprox(rb.objects[i].R, 1e-12)) << seed;
      EXPECT_TRUE(ra.objects[i].t.isApprox(rb.objects[i].t, 1e-9)) << seed;
    }
  }
}

}  // namespace
