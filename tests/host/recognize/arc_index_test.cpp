// match::ArcIndex against the matcher it stands for: every reference with a search solution is a candidate
// (the index is exact), it rules most references out, and recognition gives the same answer with it.
#include <gtest/gtest.h>

#include <iostream>
#include <vector>

#include "host/library/library.hpp"
#include "host/library/model.hpp"
#include "host/library/polycubes.hpp"
#include "host/match/arc_index.hpp"
#include "host/match/inexact.hpp"
#include "host/match/node_set.hpp"
#include "host/recognize/recognizer.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/random_scene.hpp"
#include "support/merged_faces.hpp"
#include "support/polyhedra_catalog.hpp"
#include "support/same_arc_index.hpp"

namespace {

using fs::host::rec::RecognizeParams;
using fs::host::rec::Recognizer;
using fs::sim::SceneCategory;

struct Bench {
  std::vector<fs::sim::CatalogEntry> catalog;
  fs::host::Library library;  // the 120 polyhedra, then polycubes of volume <= 5 (edge 20 mm) as distractors
};

const Bench& bench() {
  static const Bench b = [] {
    Bench x{fs::test::polyhedra_catalog().catalog, fs::test::polyhedra_catalog().library};
    const auto cubes = fs::host::enumerate_polycubes(5);
    for (std::size_t v = 0; v < cubes.size(); ++v)
      for (std::size_t i = 0; i < cubes[v].size(); ++i)
        x.library.add(
            fs::host::polycube_model(cubes[v][i], 20.0, fs::host::polycube_name(static_cast<int>(v) + 1, i)));
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

// The faces of a model a sensor on the diagonal (1, 1, 1) sees, seen whole, with the unknown around them as
// the supernode.
fs::host::Pfrg view_of(const fs::host::Model& m) {
  const fs::Vec3 v = fs::Vec3(1, 1, 1).normalized();
  fs::host::Pfrg g;
  g.name = m.name + " view";
  int super = 0;
  for (const auto& n : m.graph.nodes) super = std::max(super, n.id + 1);
  for (const auto& n : m.graph.nodes)
    if (n.normal.dot(v) > 0.1) g.nodes.push_back(n);
  for (const auto& a : m.graph.arcs) {
    const bool sa = g.find(a.a) != nullptr, sb = g.find(a.b) != nullptr;
    if (sa && sb) g.arcs.push_back(a);
  }
  fs::host::PfrgNode sn;
  sn.id = super;
  sn.supernode = true;
  for (const auto& n : g.nodes) g.arcs.push_back({n.id, super, 1.0});
  g.nodes.push_back(sn);
  g.observer = v;
  g.has_observer = true;
  return g;
}

// Face f of g, its first real neighbour and the unknown around them (a part of two faces).
fs::host::Pfrg two_faces(const fs::host::Pfrg& g, int f) {
  int other = -1;
  for (const auto& a : g.arcs) {
    const int o = a.a == f ? a.b : a.b == f ? a.a : -1;
    if (o >= 0 && !g.find(o)->supernode) {
      other = o;
      break;
    }
  }
  fs::host::Pfrg out;
  out.name = g.name + " part";
  out.observer = g.observer;
  out.has_observer = true;
  int super = 0;
  for (const auto& n : g.nodes) super = std::max(super, n.id + 1);
  for (const auto& n : g.nodes)
    if (n.id == f || n.id == other) out.nodes.push_back(n);
  for (const auto& a : g.arcs)
    if (std::minmax(a.a, a.b) == std::minmax(f, other)) out.arcs.push_back(a);
  fs::host::PfrgNode sn;
  sn.id = super;
  sn.supernode = true;
  out.nodes.push_back(sn);
  out.arcs.push_back({f, super, 1.0});
  out.arcs.push_back({other, super, 1.0});
  return out;
}

TEST(ArcIndex, EveryReferenceWithASolutionIsACandidate) {
  const auto& lib = bench().library;
  std::vector<const fs::host::Pfrg*> graphs;
  for (const auto& m : lib.models) graphs.push_back(&m.graph);
  const fs::host::match::ArcIndex index(graphs);
  EXPECT_GT(index.entries(), lib.models.size());
  RecognizeParams rp;
  rp.threads = 2;
  const fs::host::match::MatchParams p = fs::host::rec::match_params(rp);
  ASSERT_TRUE(fs::host::match::ArcIndex::applies(p));
  fs::host::match::InexactMatcher matcher;
  int with_solution = 0, cube_solutions = 0, skipped = 0, checked = 0;
  std::vector<fs::host::Pfrg> scenes;
  for (auto [category, seed] : {std::pair{SceneCategory::single, 3},
                                {SceneCategory::separated, 5},
                                {SceneCategory::occluded, 7},
                                {SceneCategory::cluttered, 11},
                                {SceneCategory::cluttered, 12}}) {
    const Scan s = scan_of(category, static_cast<std::uint64_t>(seed));
    Recognizer rec(lib, rp, s.cloud.points.size());
    rec.recognize(s.cloud, &s.table);
    scenes.push_back(rec.scene_graph());
  }
  // Views of polycubes (every angle 90 degrees): the faces a sensor on the diagonal sees, whole.
  for (std::size_t k = bench().catalog.size(); k < lib.models.size(); k += 5)
    scenes.push_back(view_of(lib.models[k]));
  // Views of polyhedra with a shallow fold in view, its two faces one region (as segmentation grows over
  // them): the area condition counts the fold (RecognizeParams::match_area_fold_deg), and so must the index.
  const std::size_t first_fold = scenes.size();
  std::vector<std::size_t> fold_models;
  std::vector<int> fold_faces;  // the merged face's id (the model's face id in the view)
  for (std::size_t k = 0; k < bench().catalog.size() && fold_models.size() < 4; ++k) {
    const fs::host::Pfrg v = view_of(lib.models[k]);
    const auto fold = fs::test::shallow_fold(v, rp.match_area_fold_deg);
    if (!fold) continue;
    const double kept = v.find(fold->first)->area, merged = kept + v.find(fold->second)->area;
    if (merged <= rp.match_area_ratio * kept + rp.match_area_slack_mm2) continue;  // within the plain bound
    std::cout << lib.models[k].name << ": faces of " << kept << " and " << merged - kept << " mm2 merged\n";
    scenes.push_back(fs::test::merged_faces(v, fold->first, fold->second));
    fold_models.push_back(k);
    fold_faces.push_back(fold->first);
  }
  ASSERT_EQ(fold_models.size(), 4u);
  for (const fs::host::Pfrg& scene : scenes) {
    if (scene.nodes.size() > static_cast<std::size_t>(fs::host::match::kMaxNodes)) continue;
    std::vector<std::uint64_t> mark(lib.models.size(), 0);
    fs::host::match::ArcIndex::Scratch scratch;
    index.candidates(scene, p, mark, 1, scratch);
    for (std::size_t k = 0; k < lib.models.size(); ++k) {
      const auto& r = matcher.match(scene, lib.models[k].graph, p);
      bool solved = false;
      for (const auto& sol : r.solutions) solved = solved || !sol.partial;
      ++checked;
      with_solution += solved;
      cube_solutions += solved && k >= bench().catalog.size();
      skipped += mark[k] == 0;
      EXPECT_TRUE(!solved || mark[k] != 0)
          << lib.models[k].name << " has a solution but was ruled out, scene " << scene.name;
    }
  }
  // Not vacuous: solutions exist, and most of the references without one are ruled out (whole multi-object
  // graphs here; a part of one object rules out more).
  EXPECT_GT(with_solution, 5);
  EXPECT_GT(cube_solutions, 0)
      << "no polycube fits the distractor boxes: the check of 90-degree paths is vacuous";
  EXPECT_GT(2 * skipped, checked - with_solution) << skipped << " of " << checked;
  std::cout << "ruled out " << skipped << " of " << checked << " (reference, scene) pairs, " << with_solution
            << " with a solution (" << cube_solutions << " polycubes)\n";
  // ... nor for the folds. A part of two faces, the merged one and a neighbour, searched with TH_minlevel 2:
  // its own model has a solution only when the fold is counted, and then the index must keep it.
  fs::host::match::MatchParams p2 = p, p2_plain = p;
  p2.th_minlevel = p2_plain.th_minlevel = 2;
  p2_plain.th_area_fold_deg = 0;
  int fold_needed = 0;
  for (std::size_t i = 0; i < fold_models.size(); ++i) {
    const fs::host::Pfrg part = two_faces(scenes[first_fold + i], fold_faces[i]);
    const auto& model = lib.models[fold_models[i]].graph;
    auto solved = [&](const fs::host::match::MatchParams& q) {
      for (const auto& sol : matcher.match(part, model, q).solutions)
        if (!sol.partial) return true;
      return false;
    };
    if (!solved(p2) || solved(p2_plain)) continue;
    ++fold_needed;
    std::vector<std::uint64_t> mark(lib.models.size(), 0);
    fs::host::match::ArcIndex::Scratch scratch;
    index.candidates(part, p2, mark, 1, scratch);
    EXPECT_NE(mark[fold_models[i]], 0u) << model.name << " has a solution across its fold but was ruled out";
  }
  EXPECT_GT(fold_needed, 0) << "no merged part needs the fold: the check of the folded areas is vacuous";
}

// Libraries gathered from several files: their indexes one after the other are the index of the whole.
TEST(ArcIndex, ConcatenatedIndexesAreTheIndexOfTheWhole) {
  using fs::host::match::ArcIndex;
  const auto& lib = bench().library;
  std::vector<const fs::host::Pfrg*> graphs;
  for (const auto& m : lib.models) graphs.push_back(&m.graph);
  const ArcIndex whole(graphs);
  const std::span<const fs::host::Pfrg* const> all(graphs);
  const ArcIndex a(all.subspan(0, 57)), b(all.subspan(57, 63)), c(all.subspan(120));
  const ArcIndex* parts[] = {&a, &b, &c};
  const ArcIndex joined = ArcIndex::concat(parts);
  fs::test::expect_same_index(joined, whole);
  ASSERT_TRUE(joined.describes(graphs));
  std::vector<const fs::host::Pfrg*> reversed(graphs.rbegin(), graphs.rend());
  EXPECT_FALSE(joined.describes(reversed));  // as many references, other models
  RecognizeParams rp;
  const auto p = fs::host::rec::match_params(rp);
  ArcIndex::Scratch scratch;
  std::size_t own = 0, views = 0;
  for (std::size_t k = 0; k < lib.models.size(); k += 7, ++views) {
    const fs::host::Pfrg scene = view_of(lib.models[k]);
    std::vector<std::uint64_t> m1(lib.models.size(), 0), m2(lib.models.size(), 0);
    whole.candidates(scene, p, m1, 1, scratch);
    joined.candidates(scene, p, m2, 1, scratch);
    EXPECT_EQ(m1, m2) << lib.models[k].name;
    own += m2[k];  // (a view of two faces has no solution of three: no candidate at all)
  }
  EXPECT_GT(2 * own, views) << "most models are candidates for their own view";
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
