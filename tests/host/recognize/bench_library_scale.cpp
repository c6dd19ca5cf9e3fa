// Recognition time against library size (issue #24), the baseline before a library index: the same scans
// recognized against
//   poly120         the 120 polyhedra (scaled as bench_recognition: make_catalog, seed S)
//   cubes7          the 1,230 polycubes of volume <= 7 (edge 20 mm)
//   cubes8          the 8,152 polycubes of volume <= 8 (`facetscan library polycubes --max-volume 8`)
//   poly120+cubes8  the 120 polyhedra with the 8,152 polycubes as distractors (two .fslib files, one -l each)
// Scenes: the 120-polyhedra scenes (categories round-robin) go to poly120 and poly120+cubes8; single
// polycubes of volume <= --cube-volume seen with >= --min-faces faces go to cubes7 and cubes8. Per library:
// .fslib size, load time, resident memory of the library and of the recognizer, and per category: top-1,
// ambiguous-correct (the true model among the alternatives of the object reported there), false positives,
// CPU time per scan (one core) with matching and verification separately, search states, allocations of a
// warm recognize().
// --profile K: for K scenes per library, every reference matched alone against the scene graph (the first
// round's parameters): where matching time goes (references with and without a solution, pruning counts).
// --verbose explains every miss (the truth against the report, whether the view's edge cuts the object, scene
// regions that join several of its faces, the true model searched alone; library_scale_misses.hpp);
// --dump-misses DIR writes the clouds of the scenes with a miss or a false positive; --lookalikes counts, per
// object, the other models that fit its view as well as its own (slow).
//
//   bench_library_scale [--scenes N] [--libraries poly120,cubes7,cubes8,poly120+cubes8] [--steps 500]
//                       [--categories single,separated,occluded,empty] [--cubes-fslib cubes8.fslib]
//                       [--max-volume 8] [--cube-volume 7] [--min-faces 3] [--min-face-cells 40] [--seed S]
//                       [--noise 0.05] [--alloc-every 4] [--profile 0] [--solutions 32] [--work DIR]
//                       [--verbose] [--dump-misses DIR] [--lookalikes]
#include <malloc.h>
#include <time.h>
#include <unistd.h>

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "common/alloc_counter/alloc_counter.hpp"
#include "common/error.hpp"
#include "host/io/cloud_writers.hpp"
#include "host/library/library.hpp"
#include "host/library/mesh_files.hpp"
#include "host/library/polycubes.hpp"
#include "host/match/inexact.hpp"
#include "host/match/node_set.hpp"
#include "host/recognize/hypotheses.hpp"
#include "host/recognize/pose.hpp"
#include "host/recognize/recognizer.hpp"
#include "host/recognize/verify.hpp"
#include "hw-sim/scene/polycube_catalog.hpp"
#include "hw-sim/scene/random_scene.hpp"
#include "library_scale_misses.hpp"
#include "library_scale_scenes.hpp"
#include "support/recognize_flags.hpp"
#include "support/test_paths.hpp"

namespace {

namespace stdfs = std::filesystem;
using fs::bench::BenchScene;
using fs::host::Library;
using fs::sim::SceneCategory;
using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}
double cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}
double rss_mb() {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return std::nan("");
}
double quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto i = static_cast<std::size_t>(pos);
  const double f = pos - static_cast<double>(i);
  return i + 1 < v.size() ? v[i] * (1 - f) + v[i + 1] * f : v[i];
}
double pct(int a, int b) { return b > 0 ? 100.0 * a / b : std::nan(""); }

struct Args {
  int scenes = 40;
  std::uint64_t seed = 1;
  std::uint32_t steps = 500;
  double noise = 0.05;
  std::vector<std::string> libraries{"poly120", "cubes7", "cubes8", "poly120+cubes8"};
  std::vector<SceneCategory> categories{SceneCategory::single, SceneCategory::separated,
                                        SceneCategory::occluded, SceneCategory::empty};
  std::string cubes_fslib, work, dump_misses;
  int max_volume = 8, cube_volume = 7, min_faces = 3;
  std::size_t min_face_cells = 40;
  int alloc_every = 4, profile = 0;
  bool verbose = false, lookalikes = false;
  fs::host::rec::RecognizeParams params = [] {
    fs::host::rec::RecognizeParams p;
    p.threads = 1;
    return p;
  }();
};

// ------------------------------------------------------------------------------------------ the libraries

struct Inputs {
  stdfs::path work;
  std::string poly_fslib, cubes_small_fslib, cubes_fslib;
  std::vector<fs::sim::CatalogEntry> poly_catalog, cube_catalog;
};

// poly120.fslib from the scaled catalog; the polycube libraries from --cubes-fslib or the generator; the
// polycube scene catalog from the small library's models (the generator's mesh of each).
void prepare(const Args& a, Inputs& in, bool poly, bool cubes) {
  if (poly) {
    in.poly_catalog = fs::sim::make_catalog(
        fs::sim::read_catalog_meshes(fs::test::shared_data() / "polyhedra/polyhedra-viewer/off"),
        {.seed = a.seed});
    Library lib;
    for (const auto& e : in.poly_catalog) lib.add(fs::host::build_model(e.mesh));
    in.poly_fslib = (in.work / "poly120.fslib").string();
    lib.save(in.poly_fslib);
  }
  if (!cubes) return;
  const auto t0 = Clock::now();
  Library all;
  if (!a.cubes_fslib.empty()) {
    in.cubes_fslib = a.cubes_fslib;
    all = Library::load(a.cubes_fslib);
  } else {
    all.models = fs::host::polycube_models(fs::host::enumerate_polycubes(a.max_volume), 20.0);
    in.cubes_fslib = (in.work / ("cubes" + std::to_string(a.max_volume) + ".fslib")).string();
    all.save(in.cubes_fslib);
    std::printf("generated %zu polycubes of volume <= %d in %.1f s: %s\n", all.models.size(), a.max_volume,
                ms_since(t0) / 1e3, in.cubes_fslib.c_str());
  }
  Library small;
  for (const auto& m : all.models) {
    const auto id = fs::host::parse_polycube_name(m.name);
    if (id && id->volume <= 7) small.models.push_back(m);
  }
  in.cubes_small_fslib = (in.work / "cubes7.fslib").string();
  small.save(in.cubes_small_fslib);
  // Scene polycubes: volume <= cube_volume, meshes from the generator, sizes from the library.
  const auto gen = fs::host::enumerate_polycubes(a.cube_volume);
  std::vector<fs::Mesh> meshes;
  for (const auto& m : small.models) {
    const auto id = fs::host::parse_polycube_name(m.name);
    if (id && id->volume <= a.cube_volume)
      meshes.push_back(fs::host::polycube_mesh_of(m, gen, in.cubes_small_fslib));
  }
  in.cube_catalog = fs::sim::make_polycube_catalog(meshes);
}

struct LibrarySpec {
  std::string name;
  std::vector<std::string> files;
  bool polycube_scenes = false;
};

LibrarySpec spec_of(const std::string& name, const Inputs& in) {
  if (name == "poly120") return {name, {in.poly_fslib}, false};
  if (name == "cubes7") return {name, {in.cubes_small_fslib}, true};
  if (name == "cubes8") return {name, {in.cubes_fslib}, true};
  if (name == "poly120+cubes8") return {name, {in.poly_fslib, in.cubes_fslib}, false};
  throw fs::Error("--libraries: unknown library '" + name + "' (poly120, cubes7, cubes8, poly120+cubes8)");
}

// ------------------------------------------------------------------------------------------------ scenes

std::vector<BenchScene> polyhedra_scenes(const Args& a, const Inputs& in) {
  std::vector<BenchScene> out;
  for (int i = 0; i < a.scenes; ++i) {
    const SceneCategory cat = a.categories[static_cast<std::size_t>(i) % a.categories.size()];
    const std::uint64_t seed = a.seed + static_cast<std::uint64_t>(i);
    const auto rs = fs::sim::make_random_scene(in.poly_catalog, {.category = cat, .steps = a.steps}, seed);
    out.push_back(fs::bench::capture(rs, in.poly_catalog, seed, a.noise));
  }
  return out;
}

std::vector<BenchScene> polycube_scenes(const Args& a, const Inputs& in, int& tried) {
  return fs::bench::polycube_scenes(Library::load(in.cubes_small_fslib), in.cube_catalog, a.scenes, a.seed,
                                    a.steps, a.noise, a.min_faces, a.min_face_cells, &tried);
}

// ---------------------------------------------------------------------------------------------- the runs

struct Stats {
  int scenes = 0, objects = 0, top1 = 0, ambiguous_ok = 0, found = 0, extra = 0, phantoms = 0,
      scenes_with_fp = 0;
  int truth_hypothesis = 0, truth_verified = 0;  // objects whose true model is among the hypotheses there
  std::vector<double> cpu, match, verify, seg, states, allocs;
  std::vector<int> lookalikes;  // --lookalikes: per object, the other models that fit its view as well
  // Objects the view's edge cuts, and how many of them are top-1 / ambiguous-correct; misses whose nearest
  // report names a wrong model and no alternative (a robot would act on it as certain).
  int edge_objects = 0, edge_top1 = 0, edge_ambiguous_ok = 0, wrong_unambiguous = 0;
};

struct Profile {
  int scenes = 0;
  double ms = 0, ms_without = 0;  // all references / those without a solution
  std::int64_t refs = 0, refs_with = 0, states = 0, states_without = 0;
  std::array<std::int64_t, fs::host::match::kConditionCount> removed{};
  std::vector<double> ref_ms;  // per reference and scene
};

// Every reference alone against the whole scene graph of the last recognize(), with the first round's
// matching parameters (prepare.cpp): time, states, solutions.
void profile_references(const fs::host::rec::Recognizer& rec, const Library& lib,
                        const fs::host::rec::RecognizeParams& p, fs::host::match::InexactMatcher& matcher,
                        Profile& out) {
  const fs::host::match::MatchParams mp = fs::host::rec::match_params(p);
  const fs::host::Pfrg& scene = rec.scene_graph();
  if (scene.nodes.size() > static_cast<std::size_t>(fs::host::match::kMaxNodes)) return;
  ++out.scenes;
  for (const auto& m : lib.models) {
    const auto t0 = Clock::now();
    const auto& r = matcher.match(scene, m.graph, mp);
    const double ms = ms_since(t0);
    bool solved = false;
    for (const auto& s : r.solutions) solved = solved || !s.partial;
    ++out.refs;
    out.ms += ms;
    out.states += r.stats.states_created;
    out.ref_ms.push_back(ms);
    if (solved) {
      ++out.refs_with;
    } else {
      out.ms_without += ms;
      out.states_without += r.stats.states_created;
      for (std::size_t c = 0; c < out.removed.size(); ++c) out.removed[c] += r.stats.removed[c];
    }
  }
}

// True when some true object was not reported as its model (top-1) or some report is no hit.
bool evaluate(const BenchScene& sc, const std::vector<fs::host::rec::Hypothesis>& found, const Library& lib,
              const std::unordered_map<std::string, int>& index, Stats& s, bool verbose,
              const fs::host::rec::Recognizer* recognizer = nullptr, bool lookalikes = false) {
  bool missed = false;
  std::vector<bool> used(found.size(), false);
  for (const auto& o : sc.objects) {
    if (o.model.empty()) continue;
    const int truth = index.at(o.model);
    const auto& tm = lib.models[static_cast<std::size_t>(truth)];
    const fs::Vec3 centre = o.R * tm.center + o.t;
    ++s.objects;
    int n_alike = -1;
    if (lookalikes && recognizer) {
      n_alike = count_lookalikes(sc, o, truth, lib, *recognizer);
      s.lookalikes.push_back(n_alike);
    }
    int nearest = -1, hit = -1;
    double nearest_d = 20.0, hit_d = 10.0;
    for (std::size_t j = 0; j < found.size(); ++j) {
      const auto& m = lib.models[static_cast<std::size_t>(found[j].model)];
      const double d = (found[j].R * m.center + found[j].t - centre).norm();
      if (d < nearest_d) nearest_d = d, nearest = static_cast<int>(j);
      if (!used[j] && found[j].model == truth && d < hit_d) hit_d = d, hit = static_cast<int>(j);
    }
    if (hit >= 0) used[static_cast<std::size_t>(hit)] = true, ++s.found;
    const int top1_before = s.top1, ambiguous_ok_before = s.ambiguous_ok;
    std::string got = "nothing";
    if (nearest >= 0) {
      const auto& h = found[static_cast<std::size_t>(nearest)];
      got = lib.models[static_cast<std::size_t>(h.model)].name;
      if (h.model == truth) {
        ++s.top1;
        ++s.ambiguous_ok;
      } else {
        for (const auto& alt : h.listed_alternatives())
          if (alt.model == truth) ++s.ambiguous_ok, got += " (true model listed as an alternative)";
        s.wrong_unambiguous += h.ambiguous() ? 0 : 1;
        got += h.ambiguous() ? " [ambiguous, " + std::to_string(h.alternatives) + " alternatives"
                             : " [unambiguous";
        got += ", confidence " + std::to_string(h.confidence()).substr(0, 5) + "]";
      }
    }
    const int edge_cells = cells_on_the_edge(sc, o, tm);
    if (edge_cells > 0) {
      ++s.edge_objects;
      s.edge_top1 += s.top1 - top1_before;
      s.edge_ambiguous_ok += s.ambiguous_ok - ambiguous_ok_before;
    }
    const bool miss = nearest < 0 || found[static_cast<std::size_t>(nearest)].model != truth;
    missed = missed || miss;
    if (verbose && miss) {
      std::printf("  seed %llu %s: %s -> %s\n", static_cast<unsigned long long>(sc.seed),
                  fs::sim::to_string(sc.category), o.model.c_str(), got.c_str());
      if (recognizer)
        why_missed(sc, o, tm, nearest >= 0 ? &found[static_cast<std::size_t>(nearest)] : nullptr, lib,
                   *recognizer, edge_cells);
      if (n_alike >= 0) std::printf("    %d other models fit this view as well as the truth\n", n_alike);
    }
  }
  int extra = 0;
  for (std::size_t j = 0; j < found.size(); ++j) {
    if (used[j]) continue;
    ++extra;
    const auto& m = lib.models[static_cast<std::size_t>(found[j].model)];
    const fs::Vec3 c = found[j].R * m.center + found[j].t;
    bool near = false;
    for (const auto& o : sc.objects) {
      if (o.model.empty()) continue;
      const auto& tm = lib.models[static_cast<std::size_t>(index.at(o.model))];
      near = near || (o.R * tm.center + o.t - c).norm() < 20.0;
    }
    s.phantoms += near ? 0 : 1;
  }
  s.extra += extra;
  s.scenes_with_fp += extra > 0 ? 1 : 0;
  return missed || extra > 0;
}

// Recall before acceptance: a hypothesis of the true model near its true place (centre < 10 mm) among all
// hypotheses of the last recognize(), and among the verified ones.
void truth_among_hypotheses(const BenchScene& sc, const fs::host::rec::Recognizer& rec, const Library& lib,
                            const std::unordered_map<std::string, int>& index, Stats& s, bool verbose) {
  const auto all = rec.all_hypotheses();
  const auto verified = rec.candidates();
  for (const auto& o : sc.objects) {
    if (o.model.empty()) continue;
    const int truth = index.at(o.model);
    const auto& tm = lib.models[static_cast<std::size_t>(truth)];
    const fs::Vec3 centre = o.R * tm.center + o.t;
    auto near = [&](const fs::host::rec::Hypothesis* h) {
      return h->model == truth && (h->R * tm.center + h->t - centre).norm() < 10.0;
    };
    const bool in_all = std::any_of(all.begin(), all.end(), near);
    const bool in_verified = std::any_of(verified.begin(), verified.end(), near);
    s.truth_hypothesis += in_all ? 1 : 0;
    s.truth_verified += in_verified ? 1 : 0;
    if (verbose && !in_all) {
      // Why no hypothesis is near: the true model's hypotheses (all poses) and the nearest one's centre
      // error.
      int of_truth = 0;
      double nearest = std::numeric_limits<double>::infinity();
      for (const auto* h : all)
        if (h->model == truth) {
          ++of_truth;
          nearest = std::min(nearest, (h->R * tm.center + h->t - centre).norm());
        }
      if (of_truth == 0)
        std::printf("    %s: no hypothesis near; none of the last round's %zu hypotheses is of the model\n",
                    o.model.c_str(), all.size());
      else
        std::printf(
            "    %s: no hypothesis near; %d of the last round's %zu hypotheses are of the model, the nearest "
            "centre %.1f mm off\n",
            o.model.c_str(), of_truth, all.size(), nearest);
    }
    if (verbose && in_all && !in_verified) {
      // Why it was not verified: its best prescore and how many hypotheses scored higher.
      double best = -1.0;
      for (const auto* h : all)
        if (near(h)) best = std::max(best, h->prescore);
      const auto above =
          std::count_if(all.begin(), all.end(), [&](const auto* h) { return h->prescore > best; });
      const auto ties =
          std::count_if(all.begin(), all.end(), [&](const auto* h) { return h->prescore == best; });
      std::printf(
          "    %s: not verified; prescore %.3f, %td of %zu hypotheses above it, %td equal; %zu verified\n",
          o.model.c_str(), best, above, all.size(), ties, verified.size());
      // The coarse check: the truth's best coarse confidence and how many coarse-checked hypotheses beat it.
      double coarse = -1.0;
      for (const auto* h : all)
        if (near(h) && h->verify.hits > 0) coarse = std::max(coarse, h->verify.confidence);
      const auto checked =
          std::count_if(all.begin(), all.end(), [](const auto* h) { return h->verify.hits > 0; });
      const auto beat = std::count_if(all.begin(), all.end(), [&](const auto* h) {
        return h->verify.hits > 0 && h->verify.confidence > coarse;
      });
      double scr = -1.0;
      for (const auto* h : all)
        if (near(h)) scr = std::max(scr, h->screened);
      const auto screened =
          std::count_if(all.begin(), all.end(), [](const auto* h) { return h->screened >= 0.0; });
      const auto scr_above =
          std::count_if(all.begin(), all.end(), [&](const auto* h) { return h->screened > scr; });
      const auto scr_equal =
          std::count_if(all.begin(), all.end(), [&](const auto* h) { return h->screened == scr; });
      // The pose of the truth's best-screened hypothesis (its best prescore one when none was screened).
      const fs::host::rec::Hypothesis* pick = nullptr;
      for (const auto* h : all)
        if (near(h) && (!pick || h->screened > pick->screened ||
                        (h->screened == pick->screened && h->prescore > pick->prescore)))
          pick = h;
      std::printf(
          "    %s: screened %.3f, %td of %td screened above it, %td equal; its pose %.1f mm, %.1f deg off, "
          "%d free dims\n",
          o.model.c_str(), scr, scr_above, screened, scr_equal,
          (pick->R * tm.center + pick->t - centre).norm(),
          fs::host::rec::rotation_angle_deg_sym(pick->R, o.R, tm), pick->free_dims);
      if (coarse < 0.0)
        std::printf("    %s: not coarse-checked (%td checked)\n", o.model.c_str(), checked);
      else
        std::printf("    %s: coarse confidence %.3f, %td of %td checked above it\n", o.model.c_str(), coarse,
                    beat, checked);
    }
  }
}

struct LibraryRun {
  std::string name;
  std::size_t models = 0;
  double fslib_mb = 0, load_ms = 0, lib_rss_mb = 0, rec_rss_mb = 0, rec_ms = 0, warm_rss_mb = 0;
  std::map<SceneCategory, Stats> stats;
  Profile profile;
};

LibraryRun run_library(const Args& a, const LibrarySpec& spec, const std::vector<BenchScene>& scenes) {
  LibraryRun out;
  out.name = spec.name;
  for (const auto& f : spec.files)
    out.fslib_mb += static_cast<double>(stdfs::file_size(f)) / (1024.0 * 1024.0);
  malloc_trim(0);
  const double rss0 = rss_mb();
  auto t0 = Clock::now();
  const Library lib = fs::host::load_or_build_library(spec.files);
  out.load_ms = ms_since(t0);
  out.models = lib.models.size();
  const double rss1 = rss_mb();
  out.lib_rss_mb = rss1 - rss0;
  const std::size_t cells =
      static_cast<std::size_t>(a.steps) * fs::ScannerCalibration::bench_default().camera.height;
  t0 = Clock::now();
  auto rec = std::make_unique<fs::host::rec::Recognizer>(lib, a.params, cells);
  out.rec_ms = ms_since(t0);
  out.rec_rss_mb = rss_mb() - rss1;
  std::printf(
      "%s: %zu models, %.1f MB .fslib, loaded in %.0f ms (+%.0f MB resident), recognizer built in %.0f ms "
      "(+%.0f MB)\n",
      spec.name.c_str(), out.models, out.fslib_mb, out.load_ms, out.lib_rss_mb, out.rec_ms, out.rec_rss_mb);
  std::fflush(stdout);
  std::unordered_map<std::string, int> index;
  for (std::size_t i = 0; i < lib.models.size(); ++i) index[lib.models[i].name] = static_cast<int>(i);
  fs::host::match::InexactMatcher matcher(fs::host::match::MatcherLimits{
      std::max<std::int64_t>(a.params.max_states, 16), std::max(a.params.solutions_per_model, 1)});
  const auto t_run = Clock::now();
  for (std::size_t i = 0; i < scenes.size(); ++i) {
    const BenchScene& sc = scenes[i];
    const double c0 = cpu_ms();
    const auto& r = rec->recognize(sc.cloud, &sc.table);
    const double cpu = cpu_ms() - c0;
    const std::vector<fs::host::rec::Hypothesis> found = r.objects;
    Stats& s = out.stats[sc.category];
    ++s.scenes;
    s.cpu.push_back(cpu);
    // Stage times are wall times (one thread: the caller's); on a loaded machine they exceed the CPU time,
    // so the scan's CPU time is split by their shares.
    const double share = r.stats.total_ms > 0 ? cpu / r.stats.total_ms : 0.0;
    s.match.push_back(share * r.stats.match_ms);
    s.verify.push_back(share * r.stats.verify_ms);
    s.seg.push_back(share * (r.stats.segment_ms + r.stats.pfrg_ms));
    s.states.push_back(static_cast<double>(r.stats.states));
    if (a.verbose)
      std::printf(
          "  seed %llu %s: cpu %.0f ms, matching %.0f, verification %.0f, %lld states, %d rounds, %zu "
          "objects\n",
          static_cast<unsigned long long>(sc.seed), fs::sim::to_string(sc.category), cpu, r.stats.match_ms,
          r.stats.verify_ms, static_cast<long long>(r.stats.states), r.stats.rounds, found.size());
    if (evaluate(sc, found, lib, index, s, a.verbose, rec.get(), a.lookalikes) && !a.dump_misses.empty()) {
      stdfs::create_directories(a.dump_misses);
      const std::string path = (stdfs::path(a.dump_misses) / (spec.name + "-seed" + std::to_string(sc.seed) +
                                                              "-" + fs::sim::to_string(sc.category) + ".pcd"))
                                   .string();
      fs::host::write_cloud(path, sc.cloud);
      if (a.verbose) std::printf("    scene written to %s\n", path.c_str());
    }
    truth_among_hypotheses(sc, *rec, lib, index, s, a.verbose);
    // Every K-th scene of each category (its first included).
    if (a.alloc_every > 0 && (s.scenes - 1) % a.alloc_every == 0) {
      fs::AllocCounter counter;
      rec->recognize(sc.cloud, &sc.table);
      s.allocs.push_back(static_cast<double>(counter.process_allocations()));
    }
    if (static_cast<int>(i) < a.profile) profile_references(*rec, lib, a.params, matcher, out.profile);
    if (!a.verbose && (i + 1) % 10 == 0)
      std::fprintf(stderr, "%s: %zu / %zu scenes, %.0f s\n", spec.name.c_str(), i + 1, scenes.size(),
                   ms_since(t_run) / 1e3);
  }
  out.warm_rss_mb = rss_mb() - rss0;
  return out;
}

void report(const Args& a, const std::vector<LibraryRun>& runs) {
  std::printf(
      "\n| library | models | .fslib MB | load ms | library RSS MB | recognizer RSS MB (built / warm) |\n");
  std::printf("|---|---|---|---|---|---|\n");
  for (const auto& r : runs)
    std::printf("| %s | %zu | %.1f | %.0f | %.0f | %.0f / %.0f |\n", r.name.c_str(), r.models, r.fslib_mb,
                r.load_ms, r.lib_rss_mb, r.rec_rss_mb, r.warm_rss_mb - r.lib_rss_mb);
  std::printf(
      "\n| library, scenes | scenes | objects | top-1 | ambiguous-correct | found (model + centre < 10 mm) | "
      "false positives (objects / scenes / phantoms) | true model among the last round's hypotheses / "
      "verified | CPU ms "
      "median "
      "/ p90 | matching ms median / p90 | verification ms median / p90 | segmentation ms median | states "
      "median | warm allocs median / max |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& r : runs)
    for (const auto& [cat, s] : r.stats)
      std::printf(
          "| %s %s | %d | %d | %.1f %% | %.1f %% | %.1f %% | %d / %d / %d | %.0f / %.0f %% | %.0f / %.0f | "
          "%.0f / %.0f | %.0f / %.0f | %.0f | %.0f | %.0f / %.0f |\n",
          r.name.c_str(), fs::sim::to_string(cat), s.scenes, s.objects, pct(s.top1, s.objects),
          pct(s.ambiguous_ok, s.objects), pct(s.found, s.objects), s.extra, s.scenes_with_fp, s.phantoms,
          pct(s.truth_hypothesis, s.objects), pct(s.truth_verified, s.objects), quantile(s.cpu, 0.5),
          quantile(s.cpu, 0.9), quantile(s.match, 0.5), quantile(s.match, 0.9), quantile(s.verify, 0.5),
          quantile(s.verify, 0.9), quantile(s.seg, 0.5), quantile(s.states, 0.5), quantile(s.allocs, 0.5),
          quantile(s.allocs, 1.0));
  std::printf(
      "\n| library, scenes | objects the view's edge cuts | their top-1 (ambiguous-correct) | "
      "the others' top-1 (ambiguous-correct) | misses whose nearest report names no alternative |\n");
  std::printf("|---|---|---|---|---|\n");
  for (const auto& r : runs)
    for (const auto& [cat, s] : r.stats)
      std::printf("| %s %s | %d | %.1f %% (%.1f %%) | %.1f %% (%.1f %%) | %d |\n", r.name.c_str(),
                  fs::sim::to_string(cat), s.edge_objects, pct(s.edge_top1, s.edge_objects),
                  pct(s.edge_ambiguous_ok, s.edge_objects),
                  pct(s.top1 - s.edge_top1, s.objects - s.edge_objects),
                  pct(s.ambiguous_ok - s.edge_ambiguous_ok, s.objects - s.edge_objects), s.wrong_unambiguous);
  if (a.lookalikes) {
    // A reference, not a limit: a recognizer that chose at random among the 1 + N equally fitting models and
    // listed Hypothesis::kMaxAlternatives alternatives would be right with probability
    // min(1, (1 + kMaxAlternatives) / (1 + N)); top-1 alone with 1 / (1 + N).
    std::printf(
        "\n| library, scenes | objects | other models fit the view as well: none / 1-4 / 5-19 / 20 or more | "
        "median | top-1 of a uniform choice among them | ... with %d alternatives listed |\n",
        fs::host::rec::Hypothesis::kMaxAlternatives);
    std::printf("|---|---|---|---|---|---|\n");
    for (const auto& r : runs)
      for (const auto& [cat, s] : r.stats) {
        if (s.lookalikes.empty()) continue;
        int bins[4] = {0, 0, 0, 0};
        double top1 = 0.0, amb = 0.0;
        std::vector<double> n;
        for (int k : s.lookalikes) {
          ++bins[k == 0 ? 0 : k < 5 ? 1 : k < 20 ? 2 : 3];
          top1 += 1.0 / (1.0 + k);
          amb += std::min(1.0, (1.0 + fs::host::rec::Hypothesis::kMaxAlternatives) / (1.0 + k));
          n.push_back(k);
        }
        const int objects = static_cast<int>(s.lookalikes.size());
        std::printf("| %s %s | %d | %d / %d / %d / %d | %.0f | %.1f %% | %.1f %% |\n", r.name.c_str(),
                    fs::sim::to_string(cat), objects, bins[0], bins[1], bins[2], bins[3], quantile(n, 0.5),
                    100.0 * top1 / objects, 100.0 * amb / objects);
      }
  }
  std::printf(
      "(stage columns: the scan's CPU time split by the stages' wall-time shares; top-1 and found count "
      "objects, "
      "false positives are reported objects that are no hit, phantoms those with no true object within 20 "
      "mm)\n");
  bool any = false;
  for (const auto& r : runs) any = any || r.profile.scenes > 0;
  if (!any) return;
  std::printf(
      "\nper-reference profile (every reference alone against the whole scene graph, first-round "
      "parameters, %d scenes per library):\n",
      a.profile);
  for (const auto& r : runs) {
    const Profile& p = r.profile;
    if (p.scenes == 0) continue;
    std::printf(
        "  %s: %.0f ms per scene over %zu references (%.3f ms each, p99 %.3f, max %.2f); %.2f %% of "
        "references reach a solution; those without take %.1f %% of the time and %.1f %% of %lld states\n",
        r.name.c_str(), p.ms / p.scenes, r.models, p.ms / static_cast<double>(p.refs),
        quantile(p.ref_ms, 0.99), quantile(p.ref_ms, 1.0),
        pct(static_cast<int>(p.refs_with), static_cast<int>(p.refs)),
        100.0 * p.ms_without / std::max(p.ms, 1e-9),
        100.0 * static_cast<double>(p.states_without) / std::max<double>(1.0, static_cast<double>(p.states)),
        static_cast<long long>(p.states));
    std::printf("    candidates removed in references without a solution, per condition:");
    for (int c = 0; c < fs::host::match::kConditionCount; ++c)
      if (p.removed[static_cast<std::size_t>(c)] > 0)
        std::printf(
            " %s %lld",
            std::string(fs::host::match::condition_name(static_cast<fs::host::match::Condition>(c))).c_str(),
            static_cast<long long>(p.removed[static_cast<std::size_t>(c)]));
    std::printf("\n");
  }
}

Args parse_args(CLI::App& app, int argc, char** argv) {
  Args a;
  std::vector<std::string> categories;
  app.add_option("--scenes", a.scenes, "scenes per scene set (polyhedra: round-robin over the categories)")
      ->check(CLI::Range(1, 100000));
  app.add_option("--libraries", a.libraries, "poly120,cubes7,cubes8,poly120+cubes8")->delimiter(',');
  app.add_option("--steps", a.steps, "scan steps (grid rows)")->check(CLI::Range(10u, 1u << 20));
  app.add_option("--categories", categories, "polyhedra scenes: single,separated,occluded,empty")
      ->delimiter(',');
  app.add_option("--cubes-fslib", a.cubes_fslib, "the polycube library (default: generated, --max-volume)");
  app.add_option("--max-volume", a.max_volume, "volume of the generated polycube library")
      ->check(CLI::Range(7, 9));
  app.add_option("--cube-volume", a.cube_volume, "largest polycube placed in scenes")
      ->check(CLI::Range(1, 7));
  app.add_option("--min-faces", a.min_faces, "a polycube scene shows at least this many model faces")
      ->check(CLI::Range(1, 100));
  app.add_option("--min-face-cells", a.min_face_cells, "... each with at least this many points");
  app.add_option("--seed", a.seed, "scene i uses seed S + i; the polyhedra sizes use S");
  app.add_option("--noise", a.noise, "depth noise sigma, mm")->check(CLI::Range(0.0, 10.0));
  app.add_option(
         "--alloc-every", a.alloc_every,
         "count the allocations of a warm recognize() in every K-th scene of each category (0 = never)")
      ->check(CLI::Range(0, 1000000));
  app.add_option("--profile", a.profile, "scenes per library profiled reference by reference")
      ->check(CLI::Range(0, 100000));
  app.add_option("--work", a.work, "folder for the .fslib files (kept; default: a temporary one, removed)");
  app.add_option(
      "--area-cost", a.params.area_cost,
      "RecognizeParams::area_cost (default 0.01): area dissimilarity in the search cost, < 0 = none");
  fs::test::add_recognize_flags(app, a.params);  // pool, matching scope, verification budget, rounds
  app.add_flag("--verbose", a.verbose, "one line per scene and per miss");
  app.add_flag(
      "--lookalikes", a.lookalikes,
      "count, per object, the other models whose hypotheses fit its view as well as the truth (slow)");
  app.add_option("--dump-misses", a.dump_misses,
                 "write the cloud of every scene with a miss (not top-1) or a report that is no hit to "
                 "DIR/LIBRARY-seedN-CATEGORY.pcd");
  app.parse(argc, argv);
  if (!categories.empty()) {
    a.categories.clear();
    for (const auto& c : categories) a.categories.push_back(fs::sim::parse_scene_category(c));
  }
  return a;
}

int run(const Args& a) {
  const auto t0 = Clock::now();
  Inputs in;
  struct WorkDir {  // a temporary work folder goes, also on an error
    stdfs::path path;
    bool temp;
    ~WorkDir() {
      std::error_code ec;
      if (temp) stdfs::remove_all(path, ec);
    }
  } work{a.work.empty() ? stdfs::temp_directory_path() / ("bench_library_scale-" + std::to_string(getpid()))
                        : stdfs::path(a.work),
         a.work.empty()};
  in.work = work.path;
  stdfs::create_directories(in.work);
  bool poly = false, cube_scenes_needed = false, cube_files = false;
  for (const auto& l : a.libraries) {
    const LibrarySpec spec = spec_of(l, in);  // refuses an unknown name before any work
    poly = poly || !spec.polycube_scenes;
    cube_scenes_needed = cube_scenes_needed || spec.polycube_scenes;
    cube_files = cube_files || l.find("cubes") != std::string::npos;
  }
  prepare(a, in, poly, cube_files);
  int tried = 0;
  const auto tp = Clock::now();
  const std::vector<BenchScene> poly_scenes = poly ? polyhedra_scenes(a, in) : std::vector<BenchScene>{};
  const std::vector<BenchScene> cube_scenes =
      cube_scenes_needed ? polycube_scenes(a, in, tried) : std::vector<BenchScene>{};
  std::printf(
      "scenes: %zu of the polyhedra, %zu single polycubes of volume <= %d seen with >= %d faces (of %d "
      "drawn), %u steps, noise %.2f mm, %d solutions per reference, one thread; ready in %.0f s\n",
      poly_scenes.size(), cube_scenes.size(), a.cube_volume, a.min_faces, tried, a.steps, a.noise,
      a.params.solutions_per_model, ms_since(tp) / 1e3);
  std::vector<LibraryRun> runs;
  for (const auto& name : a.libraries) {
    const LibrarySpec spec = spec_of(name, in);
    runs.push_back(run_library(a, spec, spec.polycube_scenes ? cube_scenes : poly_scenes));
    malloc_trim(0);
  }
  report(a, runs);
  std::printf("\n%.0f s total\n", ms_since(t0) / 1e3);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "bench_library_scale: recognition time against library size (the same scans, 120 to 8,272 models)"};
  try {
    return run(parse_args(app, argc, argv));
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_library_scale: %s\n", e.what());
    return 2;
  }
}
