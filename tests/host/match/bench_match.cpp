// bench_match: states/s and time to the best solution of the inexact matcher (thesis ch. 7).
//  - BM_AllPolyhedra/mode: the 120 polyhedra of ../shared/data/polyhedra, each against a rigid partial view
//  of
//                          itself; mode 0 = first solution (TH_solutions = 1), 1 = full search (budget 50000)
//  - BM_PolyhedronView/i:  polyhedron i alone, first-solution mode
//  - BM_ByGraphSize/n:     prisms with n faces, growth with graph size (both modes)
//  - BM_Library/N/T:       one scene against the first N polyhedra, ParallelMatcher with T threads
//  - BM_LibraryAllViews/T: every polyhedron's view against all 120, T threads: time per scene, own reference
//  first
//  - BM_RecognizerLibrary/scene/N: a hw-sim scan's scene graph against N polyhedra, the recognizer's
//  parameters
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <vector>

#include <chrono>
#include "common/mesh.hpp"
#include "host/match/inexact.hpp"
#include "host/match/parallel.hpp"
#include "host/match/params.hpp"
#include "host/pfrg/pfrg.hpp"
#include "match_helpers.hpp"
#include "support/test_paths.hpp"
#include "test_graphs.hpp"

namespace {

using namespace fs::host::match;
using fs::Mat3;
using fs::Vec3;
using fs::host::Pfrg;

const Vec3 kViewDir(0, 0, -1);

struct Pair {
  std::string name;
  Pfrg model, scene;
  Mat3 R;
};

// Mode 0: the preset of FS_BENCH_PRESET (default t7.34) stopped at the first solution; mode 1: full search.
MatchParams mode_params(int mode) {
  const char* env = std::getenv("FS_BENCH_PRESET");
  MatchParams p = preset(env ? env : "t7.34");
  if (mode == 0) p.max_solutions = 1;
  return p;
}

const std::vector<Pair>& polyhedra() {
  static const std::vector<Pair> pairs = [] {
    std::vector<Pair> out;
    std::vector<std::filesystem::path> files;
    for (const auto& e :
         std::filesystem::directory_iterator(fs::test::shared_data() / "polyhedra/polyhedra-viewer/off"))
      files.push_back(e.path());
    std::sort(files.begin(), files.end());
    std::mt19937 rng(1);
    for (const auto& f : files) {
      Pair p;
      p.name = f.stem().string();
      p.model = fs::test::mesh_pfrg(fs::read_mesh(f), 50.0);
      p.R = fs::test::random_rotation(rng);
      p.scene = fs::test::rigid_view(p.model, p.R, kViewDir);
      out.push_back(std::move(p));
    }
    return out;
  }();
  return pairs;
}

fs::Mesh prism(int sides) {
  fs::Mesh m;
  m.name = "prism" + std::to_string(sides);
  for (int z = 0; z < 2; ++z)
    for (int i = 0; i < sides; ++i) {
      const double a = 2 * 3.141592653589793 * i / sides;
      m.vertices.push_back(Vec3(50 * std::cos(a), 50 * std::sin(a), 60.0 * z));
    }
  std::vector<std::uint32_t> bottom, top;
  for (int i = 0; i < sides; ++i) {
    bottom.push_back(static_cast<std::uint32_t>(sides - 1 - i));
    top.push_back(static_cast<std::uint32_t>(sides + i));
    const auto a = static_cast<std::uint32_t>(i), b = static_cast<std::uint32_t>((i + 1) % sides);
    m.faces.push_back({a, b, b + static_cast<std::uint32_t>(sides), a + static_cast<std::uint32_t>(sides)});
  }
  m.faces.push_back(bottom);
  m.faces.push_back(top);
  return m;
}

void report(benchmark::State& state, std::int64_t states, std::int64_t matches) {
  state.counters["states/s"] = benchmark::Counter(static_cast<double>(states), benchmark::Counter::kIsRate);
  state.counters["states/match"] =
      benchmark::Counter(static_cast<double>(states) / static_cast<double>(matches));
}

void BM_AllPolyhedra(benchmark::State& state) {
  const int mode = static_cast<int>(state.range(0));
  InexactMatcher m;
  const MatchParams params = mode_params(mode);
  double max_us = 0, sum_us = 0, max30_us = 0, best_sum_us = 0;
  std::int64_t states = 0, pairs = 0, correct = 0, budget_stops = 0;
  for (auto _ : state) {
    for (const Pair& p : polyhedra()) {
      const auto t0 = std::chrono::steady_clock::now();
      const MatchResult& r = m.match(p.scene, p.model, params);
      const double us =
          std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
      max_us = std::max(max_us, us);
      if (p.model.nodes.size() <= 30) max30_us = std::max(max30_us, us);
      sum_us += us;
      best_sum_us += r.stats.time_to_best_ms * 1000.0;
      states += r.stats.states_created;
      budget_stops += r.stats.stop == StopReason::kStateBudget;
      ++pairs;
      if (!r.solutions.empty() && fs::test::judge(p.model, p.R, r.solutions[0]).equivalent) ++correct;
    }
  }
  state.counters["mean_us/pair"] = sum_us / static_cast<double>(pairs);
  state.counters["mean_us_to_best"] = best_sum_us / static_cast<double>(pairs);
  state.counters["max_us/pair"] = max_us;
  state.counters["max_us/pair<=30"] = max30_us;
  state.counters["correct_first_%"] = 100.0 * static_cast<double>(correct) / static_cast<double>(pairs);
  state.counters["budget_stops"] =
      static_cast<double>(budget_stops) / static_cast<double>(state.iterations());
  state.counters["states/s"] = static_cast<double>(states) / (sum_us * 1e-6);
}

void BM_PolyhedronView(benchmark::State& state) {
  const Pair& p = polyhedra()[static_cast<std::size_t>(state.range(0))];
  InexactMatcher m;
  const MatchParams params = mode_params(0);
  std::int64_t states = 0, n = 0;
  for (auto _ : state) {
    const MatchResult& r = m.match(p.scene, p.model, params);
    states += r.stats.states_created;
    ++n;
    benchmark::DoNotOptimize(r.solutions.data());
  }
  report(state, states, n);
  state.SetLabel(p.name + " " + std::to_string(p.model.nodes.size()) + " faces, view " +
                 std::to_string(fs::test::real_ids(p.scene).size()));
}

void BM_ByGraphSize(benchmark::State& state) {
  const int faces = static_cast<int>(state.range(0));
  const int mode = static_cast<int>(state.range(1));
  const Pfrg model = fs::test::mesh_pfrg(prism(faces - 2));
  const Mat3 R = Eigen::AngleAxisd(1.2, Vec3(1, 0.2, 0).normalized()).toRotationMatrix();
  const Pfrg scene = fs::test::rigid_view(model, R, kViewDir);
  InexactMatcher m;
  const MatchParams params = mode_params(mode);
  std::int64_t states = 0, n = 0;
  for (auto _ : state) {
    const MatchResult& r = m.match(scene, model, params);
    states += r.stats.states_created;
    ++n;
  }
  report(state, states, n);
  state.SetLabel("view " + std::to_string(fs::test::real_ids(scene).size()) + " faces");
}

// Which of two references explains a view better: solution 1 of the higher level, then the lower ranking key
// (cost + zeta U); a reference without a solution explains nothing.
bool explains_better(const ReferenceResult& a, const ReferenceResult& b, double zeta) {
  if (a.solutions.empty() || b.solutions.empty()) return !a.solutions.empty();
  const auto& x = a.solutions[0];
  const auto& y = b.solutions[0];
  if (x.level != y.level) return x.level > y.level;
  return x.cost + zeta * x.unexplained < y.cost + zeta * y.unexplained;
}

void BM_Library(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const int threads = static_cast<int>(state.range(1));
  std::vector<Pfrg> refs;
  for (std::size_t i = 0; i < n; ++i) refs.push_back(polyhedra()[i % polyhedra().size()].model);
  const Pfrg& scene = polyhedra()[7].scene;
  ParallelMatcher pm(threads);
  const MatchParams params = mode_params(0);
  std::int64_t states = 0, k = 0, expanded = 0, fits = 0, candidates = 0;
  int true_rank = 0;  // rank of the view's own reference (7) among the references by solution 1
  for (auto _ : state) {
    const auto res = pm.match(scene, refs, params, 4);
    for (const auto& r : res) {
      states += r.stats.states_created;
      expanded += r.stats.states_expanded;
      fits += r.stats.fits_fast + r.stats.fits_fallback;
      candidates += r.stats.candidates;
    }
    // Reported, so that the timing is of a search that finds the right object.
    if (n > 7) {
      true_rank = 1;
      for (std::size_t i = 0; i < res.size(); ++i)
        if (i % polyhedra().size() != 7 && explains_better(res[i], res[7], params.zeta)) ++true_rank;
    }
    ++k;
  }
  report(state, states, k);
  if (n > 7) state.counters["true_ref_rank"] = true_rank;
  const auto per = [&](std::int64_t v) {
    return benchmark::Counter(static_cast<double>(v) / static_cast<double>(k));
  };
  state.counters["expanded/match"] = per(expanded);
  state.counters["fits/match"] = per(fits);
  state.counters["candidates/match"] = per(candidates);
}

// Every polyhedron's view against all 120 references (ParallelMatcher, T threads, first solution): the wall
// time per scene (mean and max over the 120 scenes) and how often the view's own reference explains it best
// (solution 1 of the highest level, then the lowest cost + zeta U; symmetric twins of the model in the
// library count as wrong). One iteration = 120 scenes.
void BM_LibraryAllViews(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  std::vector<Pfrg> refs;
  for (const auto& p : polyhedra()) refs.push_back(p.model);
  ParallelMatcher pm(threads);
  const MatchParams params = mode_params(0);
  double max_ms = 0.0, sum_ms = 0.0;
  int top1 = 0, scenes = 0;
  for (auto _ : state) {
    for (std::size_t v = 0; v < polyhedra().size(); ++v) {
      const auto t0 = std::chrono::steady_clock::now();
      const auto res = pm.match(polyhedra()[v].scene, refs, params, 1);
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      max_ms = std::max(max_ms, ms);
      sum_ms += ms;
      ++scenes;
      bool best = !res[v].solutions.empty();
      for (std::size_t i = 0; i < res.size() && best; ++i)
        if (i != v && explains_better(res[i], res[v], params.zeta)) best = false;
      top1 += best ? 1 : 0;
    }
  }
  state.counters["mean_ms/scene"] = sum_ms / scenes;
  state.counters["max_ms/scene"] = max_ms;
  state.counters["own_ref_first_%"] = 100.0 * top1 / scenes;
}

// One hw-sim scan's scene PFRG (tests/host/match/data/hwsim_*.json, written by `facetscan graph` from
// `facetscan demo` recordings) against the 120 polyhedra with the recognizer's matching parameters: preset
// t9.3, all solutions, a 20000-state budget (host/recognize RecognizeParams::max_states), one thread.
void BM_RecognizerLibrary(benchmark::State& state) {
  static const char* kScenes[] = {"hwsim_default_scene.json", "hwsim_occlusion_scene.json"};
  const auto idx = static_cast<std::size_t>(state.range(0));
  const Pfrg scene =
      fs::host::read_pfrg_json(fs::test::source_dir() / "tests/host/match/data" / kScenes[idx]);
  const auto n = static_cast<std::size_t>(state.range(1));
  std::vector<Pfrg> refs;
  for (std::size_t i = 0; i < n; ++i) refs.push_back(polyhedra()[i % polyhedra().size()].model);
  MatchParams params = preset(std::getenv("FS_BENCH_PRESET") ? std::getenv("FS_BENCH_PRESET") : "t9.3");
  params.max_states = 20000;
  ParallelMatcher pm(1, MatcherLimits{20000, 64});
  std::int64_t states = 0, k = 0, expanded = 0, fits = 0, budget_stops = 0;
  for (auto _ : state) {
    const auto res = pm.match(scene, refs, params, 16);
    for (const auto& r : res) {
      states += r.stats.states_created;
      expanded += r.stats.states_expanded;
      fits += r.stats.fits_fast + r.stats.fits_fallback;
      budget_stops += r.stats.stop == StopReason::kStateBudget;
    }
    ++k;
  }
  report(state, states, k);
  const auto per = [&](std::int64_t v) {
    return benchmark::Counter(static_cast<double>(v) / static_cast<double>(k));
  };
  state.counters["expanded/match"] = per(expanded);
  state.counters["fits/match"] = per(fits);
  state.counters["budget_stops"] = per(budget_stops);
  state.SetLabel(std::string(kScenes[idx]) + ", " + std::to_string(fs::test::real_ids(scene).size()) +
                 " faces");
}

}  // namespace

BENCHMARK(BM_RecognizerLibrary)
    ->ArgsProduct({{0, 1}, {30, 120}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_AllPolyhedra)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_PolyhedronView)->DenseRange(0, 119)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ByGraphSize)
    ->ArgsProduct({{6, 8, 10, 14, 18, 22, 26, 30}, {0, 1}})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Library)->ArgsProduct({{10, 30, 60, 120}, {1, 2}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_LibraryAllViews)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();
BENCHMARK_MAIN();
