// Regression pin of the inexact matcher's output: speed work on the search (lazy rotation fits, pair tables,
// top-k selection of the reported solutions) must not change any result. For a set of scene / reference pairs
// and presets the full solution lists (rank, state number, path, matches, arc counts, dissimilarities,
// rotation, cost, flags) and the search statistics (states, expansions, candidates, removals per condition,
// stop) are printed with round-trip precision and compared with tests/host/match/data/solutions_golden.txt,
// which was written by the matcher before those changes.
//
// Regenerate (only when a result change is intended): FS_MATCH_WRITE_GOLDEN=1 test_match
//   --gtest_filter=SolutionsRegression.*
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include "common/mesh.hpp"
#include "host/match/inexact.hpp"
#include "host/match/parallel.hpp"
#include "host/match/params.hpp"
#include "host/pfrg/pfrg.hpp"
#include "support/test_paths.hpp"
#include "test_graphs.hpp"

namespace {

using namespace fs::host::match;
using fs::Mat3;
using fs::Vec3;
using fs::host::Pfrg;

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

void print_stats(std::ostream& o, const MatchStats& st) {
  o << "  stats states=" << st.states_created << " expanded=" << st.states_expanded
    << " candidates=" << st.candidates << " removed=";
  for (int c = 0; c < kConditionCount; ++c) o << (c ? "," : "") << st.removed[static_cast<std::size_t>(c)];
  o << " leaves=" << st.leaf_solutions << " subset_removed=" << st.subset_removed
    << " solutions=" << st.solutions << " best_state=" << st.best_state << " stop=" << stop_name(st.stop)
    << " states_to_best=" << st.states_to_best << " cost_ratio=" << num(st.cost_ratio) << "\n";
}

template <class Sol>
void print_solution(std::ostream& o, const Sol& s) {
  o << "  " << s.rank << " state=" << s.state << " path=";
  for (int k : s.path) o << k << '.';
  o << " level=" << s.level << " arcs=" << s.arcs_matched << '/' << s.arcs_inserted << '/' << s.arcs_deleted
    << " diss=" << num(s.node_diss) << ',' << num(s.arc_attr_diss) << ',' << num(s.arc_struct_diss) << ','
    << num(s.rotfit_error) << " cost=" << num(s.cost) << " flags=" << s.complete << s.partial << s.degenerate
    << " R=";
  for (int i = 0; i < 9; ++i) o << (i ? "," : "") << num(s.rotation(i / 3, i % 3));
  o << " m=";
  for (const auto& m : s.matches) o << m.scene << ':' << m.ref << ' ';
  o << "\n";
}

// The first kFull solutions in full, the others as one FNV-1a digest of their full text (keeps the file
// small).
template <class Sol>
void print_solutions(std::ostream& o, std::span<const Sol> sols) {
  constexpr std::size_t kFull = 3;
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (std::size_t k = 0; k < sols.size(); ++k) {
    if (k < kFull) {
      print_solution(o, sols[k]);
      continue;
    }
    std::ostringstream line;
    print_solution(line, sols[k]);
    for (unsigned char ch : line.str()) h = (h ^ ch) * 0x100000001b3ULL;
  }
  if (sols.size() > kFull)
    o << "  +" << sols.size() - kFull << " more, digest " << std::hex << h << std::dec << "\n";
}

const std::vector<Pfrg>& polyhedra_models() {
  static const std::vector<Pfrg> models = [] {
    std::vector<std::filesystem::path> files;
    for (const auto& e :
         std::filesystem::directory_iterator(fs::test::shared_data() / "polyhedra/polyhedra-viewer/off"))
      files.push_back(e.path());
    std::sort(files.begin(), files.end());
    std::vector<Pfrg> out;
    for (const auto& f : files) out.push_back(fs::test::mesh_pfrg(fs::read_mesh(f), 50.0));
    return out;
  }();
  return models;
}

Pfrg data_graph(const char* name) {
  return fs::host::read_pfrg_json(fs::test::source_dir() / "tests/host/match/data" / name);
}

std::string run_all() {
  std::ostringstream o;
  InexactMatcher m(MatcherLimits{20000, 16});
  auto one = [&](const std::string& label, const Pfrg& scene, const Pfrg& ref, const MatchParams& p) {
    const MatchResult& r = m.match(scene, ref, p);
    o << label << " " << p.name << (p.max_solutions == 1 ? " first" : "") << "\n";
    print_stats(o, r.stats);
    print_solutions(o, r.solutions);
  };
  auto first = [](const char* name) {
    MatchParams p = preset(name);
    p.max_solutions = 1;
    return p;
  };

  // The CORNER example and the cube against itself.
  const Pfrg corner = data_graph("corner_scene.json"), cube = data_graph("cube_ref.json");
  for (const char* pr : {"t7.19", "t7.28", "t7.34", "t9.3"}) one("corner/cube", corner, cube, preset(pr));

  // Polyhedra of the public data set: a rigid view of one against itself and two others, the presets the
  // library matching uses (first solution) and full searches.
  const auto& models = polyhedra_models();
  std::mt19937 rng(5);
  const Vec3 view(0, 0, -1);
  for (std::size_t i : {7U, 23U, 61U, 104U}) {
    const Mat3 R = fs::test::random_rotation(rng);
    const Pfrg scene = fs::test::rigid_view(models[i], R, view);
    for (std::size_t j : {i, (i + 5) % models.size(), (i + 40) % models.size()}) {
      const std::string label = models[i].name + "/" + models[j].name;
      one(label, scene, models[j], first("t7.34"));
      one(label, scene, models[j], preset("fast"));
      one(label, scene, models[j], first("t9.3"));
      one(label, scene, models[j], preset("t9.3"));
      if (models[j].nodes.size() <= 12) one(label, scene, models[j], preset("t7.34"));
    }
  }

  // Scene graphs of hw-sim scans (facetscan demo -> facetscan graph) against a few references, preset t9.3
  // (the recognizer's), through the parallel matcher.
  for (const char* name : {"hwsim_default_scene.json", "hwsim_occlusion_scene.json"}) {
    if (!std::filesystem::exists(fs::test::source_dir() / "tests/host/match/data" / name)) continue;
    const Pfrg scene = data_graph(name);
    std::vector<Pfrg> refs;
    for (std::size_t j = 0; j < models.size(); j += 10) refs.push_back(models[j]);
    refs.push_back(cube);
    ParallelMatcher pm(2, MatcherLimits{20000, 16});
    MatchParams p = preset("t9.3");
    const auto res = pm.match(scene, refs, p, 16);
    for (std::size_t j = 0; j < refs.size(); ++j) {
      o << name << "/" << refs[j].name << " t9.3 parallel\n";
      print_stats(o, res[j].stats);
      print_solutions(o, std::span<const OwnedSolution>(res[j].solutions));
    }
  }
  return o.str();
}

TEST(SolutionsRegression, IdenticalToGolden) {
  const auto golden = fs::test::source_dir() / "tests/host/match/data/solutions_golden.txt";
  const std::string now = run_all();
  if (std::getenv("FS_MATCH_WRITE_GOLDEN")) {
    std::ofstream(golden, std::ios::binary) << now;
    GTEST_SKIP() << "wrote " << golden;
  }
  std::ifstream in(golden, std::ios::binary);
  ASSERT_TRUE(in) << "missing " << golden;
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string want = ss.str();
  std::istringstream a(want), b(now);
  std::string la, lb;
  int line = 0;
  while (true) {
    const bool ga = static_cast<bool>(std::getline(a, la)), gb = static_cast<bool>(std::getline(b, lb));
    ++line;
    if (!ga && !gb) break;
    ASSERT_EQ(ga, gb) << "line " << line << ": output length differs";
    ASSERT_EQ(la, lb) << "first difference at line " << line;
  }
}

}  // namespace
