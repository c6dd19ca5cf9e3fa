// Recognition benchmark (issue 10): random scenes of the 120 polyhedra (hw-sim/scene/random_scene.hpp), ideal
// scan grids with depth noise, recognized against the 120-model library; accuracy, pose errors, false
// positives, CPU time and the allocations of a warm recognize(), per scene category.
//
//   bench_recognition [--scenes N] [--seed S] [--categories single,separated,occluded,empty] [--steps 500]
//                     [--noise 0.05] [--threads 1] [--alloc-every 1] [--verbose] [--candidates] [--only I] [--preset NAME] [--min-level N] [--solutions N] [--max-states N] [--area-ratio R] [--omega DEG] [--max-solutions N] [--no-rigidity-pairs] [--scene-stats] [--dump-graph] [--max-verified N] [--verify-per-face N]
//                     [--sample-mm MM] [--seg-dist MM] [--seg-noise-factor K] [--seg-merge-angle DEG] [--refine-per-face N] [--max-refined N] [--rounds N] [--inlier-weight W]
//
// --alloc-every K: the allocation count is taken in every K-th round of the categories (all categories).
//
// Scenes are spread round-robin over the categories; scene i uses seed S + i.
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "common/alloc_counter/alloc_counter.hpp"
#include "common/error.hpp"
#include "host/library/library.hpp"
#include "host/library/model.hpp"
#include <nlohmann/json.hpp>
#include "host/pfrg/pfrg.hpp"
#include "host/recognize/pose.hpp"
#include "host/recognize/recognizer.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/random_scene.hpp"
#include "support/test_paths.hpp"

namespace {

using fs::sim::SceneCategory;

double cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto i = static_cast<std::size_t>(pos);
  const double f = pos - static_cast<double>(i);
  return i + 1 < v.size() ? v[i] * (1 - f) + v[i + 1] * f : v[i];
}

struct CategoryStats {
  int scenes = 0, objects = 0, found = 0, identity_ok = 0, reported = 0, extra = 0, scenes_with_fp = 0;
  int truth_is_alternative = 0;   // confusions whose reported object lists the true model as an alternative
  int objects_with_alternatives = 0;
  std::vector<double> rot_err, trans_err, cpu, wall, allocs, seg_ms, match_ms, verify_ms;
};

struct Args {
  int scenes = 200;
  std::uint64_t seed = 1;
  std::vector<SceneCategory> categories{SceneCategory::single, SceneCategory::separated, SceneCategory::occluded,
                                        SceneCategory::empty};
  std::uint32_t steps = 500;
  double noise = 0.05;
  int threads = 1;
  int alloc_every = 1;
  bool verbose = false;
  bool candidates = false;
  int only = -1;
  std::string preset;        // matching preset (default: the recognizer's)
  int min_level = 0;         // 0 = the recognizer's default
  int solutions = 0;         // solutions kept per model (0 = default)
  long max_states = 0;       // state budget of one match (0 = default)
  double area_ratio = -1;    // match_area_ratio (< 0 = default, 0 = off)
  double omega = -1;         // rigidity cone TH_omega in degrees (< 0 = the recognizer's default, 0 = the preset's)
  long max_solutions = 0;    // TH_solutions of one match (0 = the recognizer's default)
  bool no_rigidity_pairs = false;   // switch the level-1 rigidity off (the thesis)
  bool scene_stats = false;  // one line per scene: graph parts, faces, search states, matching time
  bool dump_graph = false;   // with --candidates: the scene PFRG JSON (for facetscan match)
  int max_verified = 0;      // hypotheses verified per round (0 = default)
  int verify_per_face = 0;   // a scene face draws at most this many into verification (0 = default)
  int refine_per_face = 0;   // 0 = default
  double inlier_weight = -1;   // RecognizeParams::inlier_weight (< 0 = default)
  int rounds = 0;            // rounds of matching + verification (0 = default)
  int max_refined = 0;       // 0 = default
  double sample_mm = -1;    // VerifyParams::sample_spacing_mm (< 0 = default)
  double seg_dist = -1;      // segmentation dist_abs_mm (< 0 = the laser default)
  double seg_noise_factor = -1;   // segmentation dist_noise_factor (< 0 = the laser default)
  double seg_merge_angle = -1;  // segmentation merge_angle_deg (< 0 = the laser default)
};

Args parse_args(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw fs::Error("argument " + k + ": missing value");
      return argv[++i];
    };
    if (k == "--scenes") a.scenes = std::stoi(value());
    else if (k == "--seed") a.seed = std::stoull(value());
    else if (k == "--steps") a.steps = static_cast<std::uint32_t>(std::stoul(value()));
    else if (k == "--noise") a.noise = std::stod(value());
    else if (k == "--threads") a.threads = std::stoi(value());
    else if (k == "--alloc-every") a.alloc_every = std::stoi(value());
    else if (k == "--verbose") a.verbose = true;
    else if (k == "--candidates") a.candidates = a.verbose = true;
    else if (k == "--only") a.only = std::stoi(value());
    else if (k == "--preset") a.preset = value();
    else if (k == "--min-level") a.min_level = std::stoi(value());
    else if (k == "--solutions") a.solutions = std::stoi(value());
    else if (k == "--max-states") a.max_states = std::stol(value());
    else if (k == "--area-ratio") a.area_ratio = std::stod(value());
    else if (k == "--omega") a.omega = std::stod(value());
    else if (k == "--max-solutions") a.max_solutions = std::stol(value());
    else if (k == "--no-rigidity-pairs") a.no_rigidity_pairs = true;
    else if (k == "--scene-stats") a.scene_stats = true;
    else if (k == "--dump-graph") a.dump_graph = a.candidates = a.verbose = true;
    else if (k == "--max-verified") a.max_verified = std::stoi(value());
    else if (k == "--verify-per-face") a.verify_per_face = std::stoi(value());
    else if (k == "--inlier-weight") a.inlier_weight = std::stod(value());
    else if (k == "--rounds") a.rounds = std::stoi(value());
    else if (k == "--refine-per-face") a.refine_per_face = std::stoi(value());
    else if (k == "--max-refined") a.max_refined = std::stoi(value());
    else if (k == "--sample-mm") a.sample_mm = std::stod(value());
    else if (k == "--seg-dist") a.seg_dist = std::stod(value());
    else if (k == "--seg-noise-factor") a.seg_noise_factor = std::stod(value());
    else if (k == "--seg-merge-angle") a.seg_merge_angle = std::stod(value());
    else if (k == "--categories") {
      a.categories.clear();
      std::string list = value();
      std::size_t start = 0;
      while (start <= list.size()) {
        const std::size_t comma = std::min(list.find(',', start), list.size());
        a.categories.push_back(fs::sim::parse_scene_category(list.substr(start, comma - start)));
        start = comma + 1;
      }
    } else {
      throw fs::Error("unknown argument '" + k +
                      "' (--scenes N --seed S --categories a,b --steps K --noise MM --threads T --alloc-every K "
                      "--verbose)");
    }
  }
  if (a.scenes < 1 || a.steps < 10 || a.alloc_every < 0) throw fs::Error("arguments out of range");
  return a;
}

int run(const Args& args) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto catalog = fs::sim::make_catalog(
      fs::sim::read_catalog_meshes(fs::test::shared_data() / "polyhedra/polyhedra-viewer/off"), {.seed = args.seed});
  fs::host::Library library;
  for (const auto& e : catalog) library.add(fs::host::build_model(e.mesh));
  std::printf("library: %zu models built in %.1f s\n", library.models.size(),
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());

  fs::host::rec::RecognizeParams params;
  params.threads = args.threads;
  if (!args.preset.empty()) params.match = fs::host::match::preset(args.preset);
  if (args.min_level > 0) params.min_level = args.min_level;
  if (args.solutions > 0) params.solutions_per_model = args.solutions;
  if (args.max_states > 0) params.max_states = args.max_states;
  if (args.area_ratio >= 0) params.match_area_ratio = args.area_ratio;
  if (args.omega >= 0) params.rigidity_deg = args.omega;
  if (args.max_solutions > 0) params.max_solutions = args.max_solutions;
  if (args.no_rigidity_pairs) params.rigidity_pairs = false;
  if (args.max_verified > 0) params.max_verified = args.max_verified;
  if (args.verify_per_face > 0) params.verify_per_face = args.verify_per_face;
  if (args.inlier_weight >= 0) params.inlier_weight = args.inlier_weight;
  if (args.rounds > 0) params.rounds = args.rounds;
  if (args.refine_per_face > 0) params.refine_per_face = args.refine_per_face;
  if (args.max_refined > 0) params.max_refined = args.max_refined;
  if (args.sample_mm >= 0) params.verify.sample_spacing_mm = args.sample_mm;
  if (args.seg_dist >= 0) params.segment.dist_abs_mm = args.seg_dist;
  if (args.seg_noise_factor >= 0) params.segment.dist_noise_factor = args.seg_noise_factor;
  if (args.seg_merge_angle >= 0) params.segment.merge_angle_deg = args.seg_merge_angle;
  const std::size_t cells =
      static_cast<std::size_t>(args.steps) * fs::ScannerCalibration::bench_default().camera.height;
  fs::host::rec::Recognizer recognizer(library, params, cells);

  std::map<SceneCategory, CategoryStats> stats;
  std::map<std::string, int> missed_models, confused_with;
  fs::host::OrganizedCloud cloud;
  for (int i = 0; i < args.scenes; ++i) {
    if (args.only >= 0 && i != args.only) continue;
    const SceneCategory cat = args.categories[static_cast<std::size_t>(i) % args.categories.size()];
    const std::uint64_t seed = args.seed + static_cast<std::uint64_t>(i);
    const auto rs = fs::sim::make_random_scene(catalog, {.category = cat, .steps = args.steps}, seed);
    fs::sim::make_ground_truth_grid(rs.scene, {.depth_noise_mm = args.noise, .seed = seed}).export_to(cloud, false);
    const fs::Plane table = rs.scene.calibration.table;

    const auto w0 = std::chrono::steady_clock::now();
    const double c0 = cpu_ms();
    const auto& r = recognizer.recognize(cloud, &table);
    const double cpu = cpu_ms() - c0;
    const double wall = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - w0).count();
    // Copy what we evaluate: the second recognize() overwrites the result.
    std::vector<fs::host::rec::Hypothesis> found_objects = r.objects;
    const std::string note = r.note;
    if (args.scene_stats)
      std::printf("scene seed %llu %s: %d graph parts, %d faces, %lld search states, matching %.1f ms, %d hypotheses "
                  "(%d single-face), cpu %.1f ms: segmentation + PFRG %.1f, verification %.1f, %d rounds\n",
                  static_cast<unsigned long long>(seed), fs::sim::to_string(cat), r.stats.components,
                  r.stats.scene_nodes, static_cast<long long>(r.stats.states), r.stats.match_ms, r.stats.hypotheses,
                  r.stats.single_face, cpu, r.stats.segment_ms + r.stats.pfrg_ms, r.stats.verify_ms, r.stats.rounds);
    if (args.candidates) {
      std::printf("scene seed %llu: %d scene nodes, %d hypotheses\n", static_cast<unsigned long long>(seed),
                  r.stats.scene_nodes, r.stats.hypotheses);
      for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi)
        if (rs.catalog_index[oi] >= 0)
          std::printf("  truth %s\n", library.models[static_cast<std::size_t>(rs.catalog_index[oi])].name.c_str());
      if (args.dump_graph) std::printf("scene PFRG %s\n", fs::host::to_json(recognizer.scene_graph()).dump().c_str());
      for (const auto* h : recognizer.candidates())
        std::printf("  cand %-44s lvl %d faces %zu pre %.3f conf %.3f expl %.2f sup %.1f low %.1f in %d viol %d occ %d rot-to-truth %.1f\n",
                    library.models[static_cast<std::size_t>(h->model)].name.c_str(), h->level, h->matches.size(),
                    h->prescore, h->verify.confidence, h->verify.explained, h->verify.support, h->verify.lowest_mm, h->verify.inliers, h->verify.violations,
                    h->verify.occluded,
                    h->model == rs.catalog_index[0]
                        ? fs::host::rec::rotation_angle_deg_sym(rs.scene.objects[0].rotation, h->R,
                                                                library.models[static_cast<std::size_t>(h->model)])
                        : -1.0);
      for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi) {
        if (rs.catalog_index[oi] < 0) continue;
        const auto& tm = library.models[static_cast<std::size_t>(rs.catalog_index[oi])];
        const auto& ob = rs.scene.objects[oi];
        const fs::Vec3 c = ob.rotation * tm.center + ob.translation;
        std::printf("  object %s: faces", tm.name.c_str());
        for (const auto& f : tm.faces) {
          const fs::Vec3 n = ob.rotation * f.normal;
          if (n.z() > 0.05) std::printf(" [a %.0f nz %.2f]", f.area, n.z());
        }
        std::printf("\n    scene nodes near:");
        for (const auto& n : recognizer.scene_graph().nodes)
          if (!n.supernode && (n.centroid - c).norm() < tm.bounding_radius * 1.1)
            std::printf(" [%d a %.0f nz %.2f]", n.id, n.area, n.normal.z());
        std::printf("\n    arcs:");
        for (const auto& a : recognizer.scene_graph().arcs) {
          bool near = false;
          for (const auto& n : recognizer.scene_graph().nodes)
            if ((n.id == a.a || n.id == a.b) && !n.supernode && (n.centroid - c).norm() < tm.bounding_radius * 1.1) near = true;
          if (near) std::printf(" %d-%d(%.0f)", a.a, a.b, a.border);
        }
        std::printf("\n");
      }
      for (const auto* h : recognizer.all_hypotheses())
        for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi)
          if (h->model == rs.catalog_index[oi]) {
            const auto& tm = library.models[static_cast<std::size_t>(h->model)];
            std::printf("  truth-hyp %s lvl %d faces %zu pre %.3f cost %.4f rot-to-truth %.1f t-err %.1f hits %d in %d viol %d occ %d expl %.2f conf %.3f scene",
                        tm.name.c_str(), h->level, h->matches.size(), h->prescore, h->cost,
                        fs::host::rec::rotation_angle_deg_sym(rs.scene.objects[oi].rotation, h->R, tm),
                        (h->t - rs.scene.objects[oi].translation).norm(), h->verify.hits, h->verify.inliers, h->verify.violations, h->verify.occluded, h->verify.explained, h->verify.confidence);
            for (const auto& m : h->matches) std::printf(" %d", m.scene);
            std::printf("\n");
          }
    }

    CategoryStats& s = stats[cat];
    ++s.scenes;
    s.cpu.push_back(cpu);
    s.seg_ms.push_back(r.stats.segment_ms + r.stats.pfrg_ms);
    s.match_ms.push_back(r.stats.match_ms);
    s.verify_ms.push_back(r.stats.verify_ms);
    s.wall.push_back(wall);
    if (args.alloc_every > 0 && (i / static_cast<int>(args.categories.size())) % args.alloc_every == 0) {
      fs::AllocCounter counter;
      recognizer.recognize(cloud, &table);
      s.allocs.push_back(static_cast<double>(counter.process_allocations()));
    }

    std::vector<bool> used(found_objects.size(), false);
    s.reported += static_cast<int>(found_objects.size());
    for (const auto& h : found_objects) s.objects_with_alternatives += h.alternatives > 0 ? 1 : 0;
    for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi) {
      if (rs.catalog_index[oi] < 0) continue;  // the distractor box
      const auto& obj = rs.scene.objects[oi];
      const auto& truth = library.models[static_cast<std::size_t>(rs.catalog_index[oi])];
      const fs::Vec3 centre_true = obj.rotation * truth.center + obj.translation;
      ++s.objects;
      // Nearest reported object (by model centre) decides the identity; a hit needs the same model within 10 mm.
      int nearest = -1, hit = -1, any = -1;
      double nearest_d = 20.0, hit_d = 10.0, any_d = 1e300;
      for (std::size_t j = 0; j < found_objects.size(); ++j) {
        const auto& h = found_objects[j];
        const auto& m = library.models[static_cast<std::size_t>(h.model)];
        const double d = (h.R * m.center + h.t - centre_true).norm();
        if (d < nearest_d) nearest_d = d, nearest = static_cast<int>(j);
        if (d < any_d) any_d = d, any = static_cast<int>(j);
        if (!used[j] && m.name == truth.name && d < hit_d) hit_d = d, hit = static_cast<int>(j);
      }
      if (nearest >= 0 && found_objects[static_cast<std::size_t>(nearest)].model == rs.catalog_index[oi])
        ++s.identity_ok;
      if (hit >= 0) {
        used[static_cast<std::size_t>(hit)] = true;
        ++s.found;
        const auto& h = found_objects[static_cast<std::size_t>(hit)];
        s.rot_err.push_back(fs::host::rec::rotation_angle_deg_sym(obj.rotation, h.R, truth));
        s.trans_err.push_back(hit_d);
      } else {
        ++missed_models[truth.name];
        std::string got = "nothing";
        if (any >= 0) {
          const auto& h = found_objects[static_cast<std::size_t>(any)];
          got = library.models[static_cast<std::size_t>(h.model)].name + " at " + std::to_string(any_d) + " mm, " +
                std::to_string(fs::host::rec::rotation_angle_deg_sym(obj.rotation, h.R, truth)) + " deg";
        }
        if (nearest >= 0) {
          const auto& h = found_objects[static_cast<std::size_t>(nearest)];
          if (h.model != rs.catalog_index[oi]) {
            ++confused_with[truth.name + " -> " + library.models[static_cast<std::size_t>(h.model)].name];
            for (const auto& a : h.listed_alternatives())
              if (a.model == rs.catalog_index[oi]) {
                ++s.truth_is_alternative;
                got += " (true model listed as an alternative)";
              }
          }
        }
        if (args.verbose)
          std::printf("MISS seed %llu %s: %s (face %d on table, %d faces) -> nearest %s; note: %s\n",
                      static_cast<unsigned long long>(seed), fs::sim::to_string(cat), truth.name.c_str(),
                      rs.resting_face[oi], static_cast<int>(truth.faces.size()), got.c_str(), note.c_str());
      }
    }
    int extra = 0;
    for (std::size_t j = 0; j < found_objects.size(); ++j) extra += used[j] ? 0 : 1;
    s.extra += extra;
    if (extra > 0) ++s.scenes_with_fp;
    if (args.verbose && extra > 0)
      for (std::size_t j = 0; j < found_objects.size(); ++j)
        if (!used[j])
          std::printf("EXTRA seed %llu %s: reported %s (conf %.2f cost %.3f) not in the scene\n",
                      static_cast<unsigned long long>(seed), fs::sim::to_string(cat),
                      library.models[static_cast<std::size_t>(found_objects[j].model)].name.c_str(),
                      found_objects[j].verify.confidence, found_objects[j].cost);
    std::fflush(stdout);
  }

  std::printf("\n%d scenes, %u steps, depth noise %.2f mm, threads %d, seed %llu, %.0f s total\n\n", args.scenes,
              args.steps, args.noise, args.threads, static_cast<unsigned long long>(args.seed),
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  std::printf("| category | scenes | objects | found (model + centre < 10 mm) | top-1 identity | rot err median / p90 "
              "(deg) | centre err median / p90 (mm) | extra objects | scenes with a false positive | CPU ms median "
              "/ p90 | wall ms median / p90 | allocs of a warm recognize (median / max) |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& [cat, s] : stats) {
    auto pct = [](int a, int b) { return b > 0 ? 100.0 * a / b : std::nan(""); };
    std::printf("| %s | %d | %d | %d (%.1f %%) | %.1f %% | %.2f / %.2f | %.2f / %.2f | %d | %d (%.1f %%) | %.0f / %.0f "
                "| %.0f / %.0f | %.0f / %.0f |\n",
                fs::sim::to_string(cat), s.scenes, s.objects, s.found, pct(s.found, s.objects),
                pct(s.identity_ok, s.objects), quantile(s.rot_err, 0.5), quantile(s.rot_err, 0.9),
                quantile(s.trans_err, 0.5), quantile(s.trans_err, 0.9), s.extra, s.scenes_with_fp,
                pct(s.scenes_with_fp, s.scenes), quantile(s.cpu, 0.5), quantile(s.cpu, 0.9), quantile(s.wall, 0.5),
                quantile(s.wall, 0.9), quantile(s.allocs, 0.5), quantile(s.allocs, 1.0));
  }
  std::printf("\nwall time per stage (median ms; stages run on --threads workers): \n");
  for (const auto& [cat, s] : stats)
    std::printf("  %-10s segmentation + PFRG %.1f, matching %.1f, hypotheses + verification %.1f\n",
                fs::sim::to_string(cat), quantile(s.seg_ms, 0.5), quantile(s.match_ms, 0.5), quantile(s.verify_ms, 0.5));
  if (!missed_models.empty()) {
    std::printf("\nmissed models (count):");
    for (const auto& [name, n] : missed_models) std::printf(" %s:%d", name.c_str(), n);
    std::printf("\n");
  }
  if (!confused_with.empty()) {
    std::printf("confusions (truth -> reported):");
    for (const auto& [name, n] : confused_with) std::printf(" %s:%d", name.c_str(), n);
    std::printf("\n");
  }
  std::printf("alternatives (reported objects that list another model fitting as well; confusions whose true model "
              "is listed):");
  for (const auto& [cat, s] : stats)
    std::printf(" %s %d of %d objects, %d confusions;", fs::sim::to_string(cat), s.objects_with_alternatives,
                s.reported, s.truth_is_alternative);
  std::printf("\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(parse_args(argc, argv));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_recognition: %s\n", e.what());
    return 2;
  }
}
