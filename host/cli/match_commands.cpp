// facetscan isomorphisms / match (thesis ch. 5.3, 6, 7).
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/error.hpp"
#include "host/cli/commands.hpp"
#include "host/match/compact_graph.hpp"
#include "host/match/inexact.hpp"
#include "host/match/parallel.hpp"
#include "host/match/params.hpp"
#include "host/match/report.hpp"
#include "host/match/ullmann.hpp"
#include "host/pfrg/pfrg.hpp"

namespace fs::host::cli {

namespace {

struct IsoOptions {
  std::string test, ref;
  bool induced = false, mono = false, list = false;
};

struct MatchOptions {
  std::string scene;
  std::vector<std::string> refs;
  std::string params = "default";
  bool json = false;
  int solutions = 3;
  int threads = 0;
  long long max_states = 0;
  double max_time_ms = 0;
  bool show_params = false;
};

// A graph file the matchers cannot take (more nodes than they hold: match::CompactGraph::load refuses it) is
// refused when it is read, the error naming the file.
Pfrg read_graph(const std::string& path, bool include_supernodes) {
  Pfrg g = read_pfrg_json(path);
  const auto check = std::make_unique<match::CompactGraph>();
  try {
    check->load(g, include_supernodes);
  } catch (const Error& e) {
    throw Error(path + ": " + e.what());
  }
  return g;
}

void run_isomorphisms(const IsoOptions& o) {
  const Pfrg t = read_graph(o.test, false);
  const Pfrg r = read_graph(o.ref, false);
  const auto mode = o.mono ? match::ExactMode::kMonomorphism : match::ExactMode::kInduced;
  match::ExactMappingFn fn;
  if (o.list) {
    fn = [](std::span<const std::pair<int, int>> m) {
      std::string line;
      for (const auto& [a, b] : m) line += fmt::format(" {}->{}", a, b);
      std::printf("%s\n", line.c_str() + (line.empty() ? 0 : 1));
    };
  }
  const match::ExactStats st = match::count_isomorphisms(t, r, mode, fn);
  std::printf("%llu %s (search states %llu, refinement removals %llu)\n",
              static_cast<unsigned long long>(st.count), o.mono ? "monomorphisms" : "isomorphisms",
              static_cast<unsigned long long>(st.tree_nodes),
              static_cast<unsigned long long>(st.refinement_removals));
}

void run_match(const MatchOptions& o) {
  match::MatchParams p = match::read_params(o.params);
  if (o.max_states > 0) p.max_states = o.max_states;
  if (o.max_time_ms > 0) p.max_time_ms = o.max_time_ms;
  const Pfrg scene = read_graph(o.scene, true);
  std::vector<Pfrg> refs;
  for (const auto& f : o.refs) refs.push_back(read_graph(f, true));
  match::MatcherLimits limits;
  limits.max_states = std::max<long long>(p.max_states, 1);
  limits.max_reported = std::max(o.solutions, 1);
  nlohmann::json out = nlohmann::json::array();
  if (refs.size() == 1) {
    match::InexactMatcher m(limits);
    const match::MatchResult& r = m.match(scene, refs[0], p);
    if (o.json) {
      auto j = match::result_json(r, scene.name, static_cast<std::size_t>(o.solutions));
      j["scene"] = scene.name;
      j["reference"] = refs[0].name;
      if (o.show_params) j["params"] = match::to_json(p);
      std::cout << j.dump(1) << "\n";
    } else {
      if (o.show_params) std::cout << match::to_json(p).dump(1) << "\n";
      std::cout << fmt::format("scene {} vs reference {} (parameters {})\n", scene.name, refs[0].name,
                               p.name);
      std::cout << match::format_result(r, scene.name, static_cast<std::size_t>(o.solutions));
    }
    return;
  }
  match::ParallelMatcher pm(o.threads, limits);
  const auto results = pm.match(scene, refs, p, static_cast<std::size_t>(o.solutions));
  for (std::size_t i = 0; i < refs.size(); ++i) {
    const auto& rr = results[i];
    if (o.json) {
      nlohmann::json sols = nlohmann::json::array();
      for (const auto& s : rr.solutions) {
        nlohmann::json m = nlohmann::json::array();
        for (const auto& x : s.matches) m.push_back({x.scene, x.ref});
        sols.push_back({{"rank", s.rank},
                        {"id", match::state_id(scene.name, s.path)},
                        {"level", s.level},
                        {"cost", s.cost},
                        {"rotfit_error", s.rotfit_error},
                        {"matches", m},
                        {"rotation",
                         {{s.rotation(0, 0), s.rotation(0, 1), s.rotation(0, 2)},
                          {s.rotation(1, 0), s.rotation(1, 1), s.rotation(1, 2)},
                          {s.rotation(2, 0), s.rotation(2, 1), s.rotation(2, 2)}}},
                        {"complete", s.complete}});
      }
      out.push_back({{"reference", refs[i].name},
                     {"solutions", sols},
                     {"stats",
                      {{"states", rr.stats.states_created},
                       {"solutions", rr.stats.solutions},
                       {"time_ms", rr.stats.time_ms},
                       {"stop", std::string(match::stop_name(rr.stats.stop))}}}});
    } else {
      std::cout << fmt::format("reference {}: {} solutions, {} states, {:.3f} ms, stop: {}\n", refs[i].name,
                               rr.stats.solutions, rr.stats.states_created, rr.stats.time_ms,
                               match::stop_name(rr.stats.stop));
      for (const auto& s : rr.solutions) {
        std::string m;
        for (const auto& x : s.matches) m += fmt::format(" {}/{}", x.scene, x.ref);
        std::cout << fmt::format("  {} {} level {} cost {:.5E} rotfit {:.3E} sce/ref:{}\n", s.rank,
                                 match::state_id(scene.name, s.path), s.level, s.cost, s.rotfit_error, m);
      }
    }
  }
  if (o.json) std::cout << nlohmann::json{{"scene", scene.name}, {"references", out}}.dump(1) << "\n";
}

}  // namespace

void add_match_commands(CLI::App& app) {
  auto iso = std::make_shared<IsoOptions>();
  auto* c =
      app.add_subcommand("isomorphisms", "Exact matching (Ullmann): count the mappings of TEST into REF");
  c->add_option("test", iso->test, "test PFRG JSON")->required()->check(CLI::ExistingFile);
  c->add_option("ref", iso->ref, "reference PFRG JSON")->required()->check(CLI::ExistingFile);
  auto* ind =
      c->add_flag("--induced", iso->induced, "subgraph isomorphism (default): arcs and non-arcs agree");
  auto* mono = c->add_flag("--monomorphism", iso->mono, "subgraph check: every test arc has a reference arc");
  ind->excludes(mono);
  c->add_flag("--list", iso->list, "print every mapping (test->ref node ids)");
  c->callback([iso] { run_isomorphisms(*iso); });

  auto mo = std::make_shared<MatchOptions>();
  auto* m =
      app.add_subcommand("match", "Inexact best-first PFRG matching (thesis ch. 7): SCENE against REF...");
  m->add_option("scene", mo->scene, "scene PFRG JSON")->required()->check(CLI::ExistingFile);
  m->add_option("refs", mo->refs, "reference PFRG JSON file(s)")->required()->check(CLI::ExistingFile);
  m->add_option(
      "--params", mo->params,
      "parameter preset (t7.19 t7.28 t7.30 t7.32 t7.34 = default, t7.41 t9.3 fast scan) or JSON file");
  m->add_flag("--json", mo->json, "JSON output on stdout");
  m->add_option("--solutions", mo->solutions, "solutions to print (default 3)")->check(CLI::Range(1, 100000));
  m->add_option("--threads", mo->threads, "threads for several references (default: all cores)");
  m->add_option("--max-states", mo->max_states, "state budget (overrides the parameters)");
  m->add_option("--max-time-ms", mo->max_time_ms, "time budget in ms (overrides the parameters)");
  m->add_flag("--show-params", mo->show_params, "print the parameters used");
  m->callback([mo] { run_match(*mo); });
}

}  // namespace fs::host::cli
