// Recognition benchmark: random scenes of the 120 polyhedra (hw-sim/scene/random_scene.hpp), ideal
// scan grids with depth noise, recognized against the 120-model library. Per scene category: recall (found),
// top-1 identity, pose errors, false positives (also as a share of the reported objects), ambiguous reports
// (listing alternatives) and how many of them name the true model, the confusions (true model -> reported
// model), CPU time median / p90 and the allocations of a warm recognize(); for cluttered scenes also the
// stacked objects found. Exits 1 when two reported solids interpenetrate.
//
//   bench_recognition [--scenes N] [--seed S] [--categories single,separated,occluded,empty,cluttered]
//                     [--steps 500] [--noise 0.05] [--row-step 1] [--threads 1] [--alloc-every 1] [--verbose]
//                     [--candidates] [--only I] [--scene-stats] [--dump-graph]
//                     [--rig bench|oblique] [--as-cloud] [--dropout 0.01] [--sizes 40,80]
// and tuning options that each set one RecognizeParams field: matching (--preset, --min-level, --max-states,
// --area-ratio, --area-cost, --omega, --max-solutions, --no-rigidity-pairs), acceptance (--replace-better,
// --support-radius, --min-confidence, --hidden-*, --occluded-alternatives), verification and segmentation
// (--sample-mm, --seg-*), and those shared with bench_library_scale (tests/support/recognize_flags.hpp: pool,
// matching scope, verification budget, rounds). `--help` lists them with their meaning.
//
// --alloc-every K: the allocation count is taken in every K-th round of the categories (all categories).
//
// Scenes are spread round-robin over the categories; scene i uses seed S + i.
//
// Another scanner's clouds: `--rig oblique` renders with hw-sim/scene/oblique_rig.hpp's geometry (camera in
// front and tilted, laser from behind; objects placed in x [-100, 100], y [-85, 85]), `--as-cloud` recognizes
// each scan as a point cloud of unknown origin (no calibration, the table found by the recognizer, as a
// PCD / PLY file is), `--dropout P` loses each measured point with probability P, `--sizes MIN,MAX` draws the
// polyhedra's largest extents. E.g. clouds like ../shared/data/independent-scans/:
//   bench_recognition --rig oblique --steps 240 --as-cloud --noise 0.08 --dropout 0.01 --sizes 55,85
#include <time.h>

#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include "common/alloc_counter/alloc_counter.hpp"
#include "common/error.hpp"
#include "host/library/library.hpp"
#include "host/library/model.hpp"
#include "host/pfrg/pfrg.hpp"
#include "host/recognize/pose.hpp"
#include "host/recognize/recognizer.hpp"
#include "host/recognize/verify.hpp"
#include "host/segment/row_thinning.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/oblique_rig.hpp"
#include "hw-sim/scene/random_scene.hpp"
#include "support/quantile.hpp"
#include "support/recognize_flags.hpp"
#include "support/test_paths.hpp"

namespace {

using fs::sim::SceneCategory;

double cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

using fs::test::quantile;

// A face counts as seen when the scan measures it in this many grid cells or more (before any dropout).
constexpr std::size_t kSeenFaceCells = 30;

struct CategoryStats {
  int scenes = 0, objects = 0, found = 0, identity_ok = 0, reported = 0, extra = 0, scenes_with_fp = 0;
  int truth_is_alternative = 0;  // confusions whose reported object lists the true model as an alternative
  // Reported objects that list alternatives ("ambiguous"), and those of them whose true model (of the scene
  // object they were matched to, else of the nearest one within 20 mm) is the reported model or listed, in a
  // pose whose centre is within 10 mm of the truth.
  int ambiguous = 0, ambiguous_correct = 0;
  // Issue #20's scoring: a missed object counts as found when an otherwise unmatched report within 10 mm is
  // ambiguous with its true model among the candidates (that report is then no false positive).
  int found_as_candidate = 0;
  int stacked = 0, stacked_found = 0;  // objects resting on another one (cluttered)
  int seen3 = 0, seen3_found = 0;      // objects with 3 faces or more measured in kSeenFaceCells cells each
  // Of those missed: nothing reported within 20 mm, or the truth fits the view at least as well as the
  // report.
  int seen3_unreported = 0, seen3_truth_fits = 0;
  int interpenetrating_pairs = 0;         // accepted pairs whose solids interpenetrate (must stay 0)
  std::map<std::string, int> confusions;  // "true -> reported" for identity errors; "*" = true model listed
  std::vector<double> rot_err, trans_err, cpu, wall, allocs, seg_ms, match_ms, verify_ms;
  int thinned = 0;  // scans segmented on every other row (RecognizeParams::segment_row_step)
  // Reported objects by their reported confidence (Hypothesis::confidence(), ambiguity included; bins
  // kConfidenceBins) and the faces their search matched (2 or fewer, 3 or more), correct (issue #20's
  // scoring) or false: what a robot that acts only above a confidence would get.
  std::array<std::array<int, 5>, 2> conf_correct{}, conf_false{};
};

// Lower edges of the confidence bins of CategoryStats::conf_*.
constexpr std::array<double, 5> kConfidenceBins{0.0, 0.7, 0.8, 0.9, 0.95};

struct Args {
  int scenes = 200;
  std::uint64_t seed = 1;
  std::vector<SceneCategory> categories{SceneCategory::single, SceneCategory::separated,
                                        SceneCategory::occluded, SceneCategory::empty,
                                        SceneCategory::cluttered};
  std::uint32_t steps = 500;
  double noise = 0.05;
  std::uint32_t row_step = 1;  // recognize every k-th row of the cloud
  int alloc_every = 1;
  bool verbose = false;
  bool candidates = false;
  int only = -1;
  bool scene_stats = false;   // one line per scene: graph parts, faces, search states, matching time
  bool dump_graph = false;    // with --candidates: the scene PFRG JSON (for facetscan match)
  std::string rig = "bench";  // "bench" (ScannerCalibration::bench_default) or "oblique" (oblique_rig)
  bool as_cloud = false;      // recognize without the calibration and the table plane
  double dropout = 0.0;       // share of measured points lost
  std::vector<double> sizes{40.0, 80.0};  // the polyhedra's largest extent, mm (CatalogOptions)
  // The recognizer's parameters: its defaults (one thread), with the tuning options below written into them.
  fs::host::rec::RecognizeParams params = [] {
    fs::host::rec::RecognizeParams p;
    p.threads = 1;
    return p;
  }();
};

// value >= lo (CLI11 2.1's PositiveNumber / NonNegativeNumber name the whole range up to DBL_MAX in their
// message).
CLI::Validator at_least(double lo, const std::string& text) {
  return CLI::Validator(
      [lo, text](std::string& v) -> std::string {
        char* end = nullptr;
        const double d = std::strtod(v.c_str(), &end);
        if (end == v.c_str() || *end != '\0') return "expected a number, got '" + v + "'";
        return d >= lo ? std::string() : "expected " + text + ", got " + v;
      },
      text);
}

// Throws CLI::ParseError (main prints it, or the help, through CLI::App::exit).
Args parse_args(CLI::App& app, int argc, char** argv) {
  const CLI::Validator positive = at_least(1, ">= 1"), non_negative = at_least(0, ">= 0");
  Args a;
  fs::host::rec::RecognizeParams& p = a.params;
  std::vector<std::string> categories;
  std::string preset;
  app.add_option("--scenes", a.scenes, "scenes, spread round-robin over the categories")->check(positive);
  app.add_option("--seed", a.seed, "scene i uses seed S + i");
  app.add_option("--categories", categories, "single,separated,occluded,empty,cluttered (all by default)")
      ->delimiter(',');
  app.add_option("--steps", a.steps, "scan steps (grid rows)")->check(CLI::Range(10u, 1u << 20));
  app.add_option("--noise", a.noise, "depth noise sigma, mm")->check(non_negative);
  app.add_option("--row-step", a.row_step, "recognize only every K-th row of each scan's cloud")
      ->check(CLI::Range(1, 64));
  app.add_option("--segment-row-step", p.segment_row_step,
                 "RecognizeParams::segment_row_step: 2 = segment every other row where the rows lie densely")
      ->check(CLI::Range(1, 2));
  app.add_option("--threads", p.threads, "recognizer threads (0 = all cores)")->check(non_negative);
  app.add_option(
         "--alloc-every", a.alloc_every,
         "count the allocations of a warm recognize() in every K-th round of the categories (0 = never)")
      ->check(non_negative);
  app.add_flag("--verbose", a.verbose, "per-object lines for misses and extras");
  app.add_flag("--candidates", a.candidates, "the hypotheses of each scene (implies --verbose)");
  app.add_option("--only", a.only, "run only scene I");
  app.add_flag("--scene-stats", a.scene_stats,
               "one line per scene: graph parts, faces, search states, CPU and stage times");
  app.add_flag("--dump-graph", a.dump_graph, "the scene PFRG JSON (implies --candidates)");
  // Tuning: each writes one RecognizeParams field; left out, the recognizer's default stays.
  app.add_option("--rig", a.rig, "scanner geometry: bench (the default rig) or oblique (oblique_rig.hpp)")
      ->check(CLI::IsMember({"bench", "oblique"}));
  app.add_flag(
      "--as-cloud", a.as_cloud,
      "recognize each scan as a cloud of unknown origin: no calibration, the table found, not given");
  app.add_option("--dropout", a.dropout, "share of measured points lost (NaN)")->check(CLI::Range(0.0, 0.9));
  app.add_option("--sizes", a.sizes, "MIN,MAX: the polyhedra's largest extent, mm")
      ->delimiter(',')
      ->expected(2)
      ->check(CLI::Range(1.0, 1000.0));
  app.add_option("--preset", preset, "matching preset (match::preset)");
  app.add_option("--min-level", p.min_level, "TH_minlevel")->check(positive);
  fs::test::add_recognize_flags(app, p);  // pool, matching scope, verification budget, rounds
  app.add_option("--area-ratio", p.match_area_ratio, "match_area_ratio (0 = off)")->check(non_negative);
  app.add_option(
         "--area-fold", p.match_area_fold_deg,
         "RecognizeParams::match_area_fold_deg (default 15): the area condition counts a model face's "
         "neighbours across folds up to this angle; 0 = the face alone")
      ->check(CLI::Range(0.0, fs::host::match::kAreaFoldMaxDeg));
  app.add_option("--area-cost", p.area_cost,
                 "weight of the area dissimilarity in the search cost (< 0 = the preset's)");
  app.add_option("--omega", p.rigidity_deg, "rigidity cone TH_omega, degrees (0 = the preset's)")
      ->check(non_negative);
  app.add_option("--max-solutions", p.max_solutions, "TH_solutions of one match")->check(positive);
  app.add_flag("--no-rigidity-pairs{false}", p.rigidity_pairs,
               "switch the level-1 rigidity off (the thesis)");
  app.add_option("--replace-better", p.replace_better, "RecognizeParams::replace_better (> 1 = off)")
      ->check(non_negative);
  app.add_option("--lone-hidden-ratio", p.single_face_hidden_min_area_ratio,
                 "RecognizeParams::single_face_hidden_min_area_ratio (default 0.35; 0 = off)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option(
      "--lone-raised", p.single_face_raised,
      "RecognizeParams::single_face_raised (default 1: a lone top face may rest on a hidden object)");
  app.add_option("--lone-hidden-confidence", p.single_face_hidden_min_confidence,
                 "RecognizeParams::single_face_hidden_min_confidence (default 0.9)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--replace-violation-weight", p.replace_violation_weight,
                 "RecognizeParams::replace_violation_weight (default 2; 0 = off)")
      ->check(non_negative);
  app.add_option(
         "--support-radius", p.support_radius_mm,
         "RecognizeParams::support_radius_mm (0 = only the table or an accepted object holds a solid up)")
      ->check(non_negative);
  app.add_option("--min-confidence", p.min_confidence, "RecognizeParams::min_confidence")
      ->check(non_negative);
  app.add_option("--hidden-below-faces", p.hidden_below_min_faces, "RecognizeParams::hidden_below_min_faces");
  app.add_option("--hidden-below-fit", p.hidden_below_min_fit, "RecognizeParams::hidden_below_min_fit");
  app.add_option("--hidden-alternatives", p.hidden_alternatives,
                 "RecognizeParams::hidden_alternatives (0 = none)");
  app.add_option("--occluded-alternatives", p.occluded_alternatives_share,
                 "RecognizeParams::occluded_alternatives_share (> 1 = never)")
      ->check(non_negative);
  app.add_flag("--no-hidden-below{false}", p.support_hidden_below,
               "RecognizeParams::support_hidden_below off (space hidden under a solid does not hold it up)");
  app.add_option("--hidden-min-confidence", p.hidden_min_confidence, "RecognizeParams::hidden_min_confidence")
      ->check(non_negative);
  app.add_option("--sample-mm", p.verify.sample_spacing_mm,
                 "VerifyParams::sample_spacing_mm (0 = every sample_step-th cell)")
      ->check(non_negative);
  app.add_option("--seg-dist", p.segment.dist_abs_mm, "segmentation dist_abs_mm")->check(non_negative);
  app.add_option("--seg-noise-factor", p.segment.dist_noise_factor, "segmentation dist_noise_factor")
      ->check(non_negative);
  app.add_option("--seg-merge-angle", p.segment.merge_angle_deg, "segmentation merge_angle_deg")
      ->check(non_negative);
  app.add_option("--seg-normal-span-mm", p.segment.normal_span_mm,
                 "segmentation normal_span_mm: the normals' span on a coarse grid (0 = normal_span cells)")
      ->check(non_negative);
  app.add_option(
         "--seg-jump-spacing", p.segment.jump_spacing_factor,
         "segmentation jump_spacing_factor: jump threshold floor in grid spacings (0 = jump_abs_mm alone)")
      ->check(non_negative);
  app.parse(argc, argv);
  if (!categories.empty()) {
    a.categories.clear();
    for (const std::string& c : categories) a.categories.push_back(fs::sim::parse_scene_category(c));
  }
  if (a.sizes[0] > a.sizes[1]) throw CLI::ValidationError("--sizes", "MIN must not exceed MAX");
  if (!preset.empty()) p.match = fs::host::match::preset(preset);  // p.match holds none of the options above
  a.candidates = a.candidates || a.dump_graph;
  a.verbose = a.verbose || a.candidates;
  return a;
}

int run(const Args& args) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto catalog = fs::sim::make_catalog(
      fs::sim::read_catalog_meshes(fs::test::shared_data() / "polyhedra/polyhedra-viewer/off"),
      {.min_size_mm = args.sizes[0], .max_size_mm = args.sizes[1], .seed = args.seed});
  fs::host::Library library;
  for (const auto& e : catalog) library.add(fs::host::build_model(e.mesh));
  std::printf("library: %zu models built in %.1f s\n", library.models.size(),
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());

  const fs::host::rec::RecognizeParams& params = args.params;
  const bool oblique = args.rig == "oblique";
  const std::size_t cells =
      static_cast<std::size_t>(args.steps) *
      (oblique ? fs::sim::oblique_rig(args.steps) : fs::ScannerCalibration::bench_default()).camera.height;
  fs::host::rec::Recognizer recognizer(library, params, cells);

  std::map<SceneCategory, CategoryStats> stats;
  std::map<std::string, int> missed_models;
  fs::host::OrganizedCloud cloud, thinned;  // thinned: --row-step
  for (int i = 0; i < args.scenes; ++i) {
    if (args.only >= 0 && i != args.only) continue;
    const SceneCategory cat = args.categories[static_cast<std::size_t>(i) % args.categories.size()];
    const std::uint64_t seed = args.seed + static_cast<std::uint64_t>(i);
    const fs::sim::RandomSceneOptions scene_options{.category = cat, .steps = args.steps};
    const auto rs = oblique ? fs::sim::make_oblique_scene(catalog, scene_options, seed)
                            : fs::sim::make_random_scene(catalog, scene_options, seed);
    const fs::sim::GroundTruthGrid grid =
        fs::sim::make_ground_truth_grid(rs.scene, {.depth_noise_mm = args.noise, .seed = seed});
    grid.export_to(cloud, false);
    // Measured cells per scene object (index oi + 1) and face.
    std::vector<std::vector<std::size_t>> face_cells(rs.scene.objects.size() + 1);
    for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi)
      face_cells[oi + 1].assign(rs.scene.objects[oi].mesh.faces.size(), 0);
    for (const auto& c : grid.cells())
      if (c.object > 0) ++face_cells[static_cast<std::size_t>(c.object)][static_cast<std::size_t>(c.face)];
    if (args.dropout > 0) fs::sim::drop_points(cloud, args.dropout, seed);
    if (args.as_cloud) cloud.scanner.reset();
    const fs::Plane table_plane = rs.scene.calibration.table;
    const fs::Plane* table = args.as_cloud ? nullptr : &table_plane;
    if (args.row_step > 1) {
      fs::host::seg::thin_rows(cloud, args.row_step, thinned);
      std::swap(cloud, thinned);
    }

    const auto w0 = std::chrono::steady_clock::now();
    const double c0 = cpu_ms();
    const auto& r = recognizer.recognize(cloud, table);
    const double cpu = cpu_ms() - c0;
    const double wall =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - w0).count();
    // Copy what we evaluate: the second recognize() overwrites the result.
    std::vector<fs::host::rec::Hypothesis> found_objects = r.objects;
    const std::string note = r.note;
    // Fine samples of this scan, built on first use (verify_on_fine).
    fs::host::rec::SampleSet fine_samples;
    bool fine_built = false;
    fs::host::rec::Verifier fine_verifier(params.verify);
    auto verify_on_fine = [&](const fs::host::Model& m, fs::Mat3 R, fs::Vec3 t) {
      if (!fine_built) {
        fine_samples.build(
            cloud, fs::host::rec::sample_steps(fs::host::rec::grid_spacing_mm(cloud),
                                               params.verify.sample_step, params.verify.sample_spacing_mm));
        fine_built = true;
      }
      return fine_verifier.verify(fine_samples, fs::host::rec::ModelGeometry(m), R, t, false);
    };
    if (args.scene_stats)
      std::printf(
          "scene seed %llu %s: %d graph parts, %d faces, %lld search states, matching %.1f ms, %d hypotheses "
          "(%d single-face), cpu %.1f ms: segmentation + PFRG %.1f, verification %.1f, %d rounds\n",
          static_cast<unsigned long long>(seed), fs::sim::to_string(cat), r.stats.components,
          r.stats.scene_nodes, static_cast<long long>(r.stats.states), r.stats.match_ms, r.stats.hypotheses,
          r.stats.single_face, cpu, r.stats.segment_ms + r.stats.pfrg_ms, r.stats.verify_ms, r.stats.rounds);
    if (args.candidates) {
      std::printf("scene seed %llu: %d scene nodes, %d hypotheses\n", static_cast<unsigned long long>(seed),
                  r.stats.scene_nodes, r.stats.hypotheses);
      for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi)
        if (rs.catalog_index[oi] >= 0)
          std::printf("  truth %s\n",
                      library.models[static_cast<std::size_t>(rs.catalog_index[oi])].name.c_str());
      if (args.dump_graph)
        std::printf("scene PFRG %s\n", fs::host::to_json(recognizer.scene_graph()).dump().c_str());
      for (const auto* h : recognizer.candidates())
        std::printf(
            "  cand %-44s lvl %d faces %zu pre %.3f conf %.3f expl %.2f sup %.1f low %.1f in %d viol %d occ "
            "%d rot-to-truth %.1f\n",
            library.models[static_cast<std::size_t>(h->model)].name.c_str(), h->level, h->matches.size(),
            h->prescore, h->verify.confidence, h->verify.explained, h->verify.support, h->verify.lowest_mm,
            h->verify.inliers, h->verify.violations, h->verify.occluded,
            !rs.catalog_index.empty() && h->model == rs.catalog_index[0]
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
            if ((n.id == a.a || n.id == a.b) && !n.supernode &&
                (n.centroid - c).norm() < tm.bounding_radius * 1.1)
              near = true;
          if (near) std::printf(" %d-%d(%.0f)", a.a, a.b, a.border);
        }
        std::printf("\n");
      }
      // Each true object's model verified in its true pose on the fine samples, without refinement (compare
      // with the candidates' in / viol / occ: the samples are the same).
      for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi) {
        if (rs.catalog_index[oi] < 0) continue;
        const auto& tm = library.models[static_cast<std::size_t>(rs.catalog_index[oi])];
        const auto v = verify_on_fine(tm, rs.scene.objects[oi].rotation, rs.scene.objects[oi].translation);
        std::printf("  truth-pose %s: in %d viol %d occ %d conf %.3f\n", tm.name.c_str(), v.inliers,
                    v.violations, v.occluded, v.confidence);
      }
      for (const auto* h : recognizer.all_hypotheses())
        for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi)
          if (h->model == rs.catalog_index[oi]) {
            const auto& tm = library.models[static_cast<std::size_t>(h->model)];
            std::printf(
                "  truth-hyp %s lvl %d faces %zu pre %.3f scr %.3f cost %.4f rot-to-truth %.1f t-err %.1f "
                "hits %d in %d viol %d occ %d expl %.2f conf %.3f support %.2f low %.1f scene",
                tm.name.c_str(), h->level, h->matches.size(), h->prescore, h->screened, h->cost,
                fs::host::rec::rotation_angle_deg_sym(rs.scene.objects[oi].rotation, h->R, tm),
                (h->t - rs.scene.objects[oi].translation).norm(), h->verify.hits, h->verify.inliers,
                h->verify.violations, h->verify.occluded, h->verify.explained, h->verify.confidence,
                h->verify.support, h->verify.lowest_mm);
            for (const auto& m : h->matches) std::printf(" %d", m.scene);
            std::printf("\n");
          }
    }

    CategoryStats& s = stats[cat];
    ++s.scenes;
    s.cpu.push_back(cpu);
    s.seg_ms.push_back(r.stats.segment_ms + r.stats.pfrg_ms);
    s.thinned += r.stats.segment_row_step > 1 ? 1 : 0;
    s.match_ms.push_back(r.stats.match_ms);
    s.verify_ms.push_back(r.stats.verify_ms);
    s.wall.push_back(wall);
    if (args.alloc_every > 0 && (i / static_cast<int>(args.categories.size())) % args.alloc_every == 0) {
      fs::AllocCounter counter;
      recognizer.recognize(cloud, table);
      s.allocs.push_back(static_cast<double>(counter.process_allocations()));
    }

    std::vector<bool> used(found_objects.size(), false);
    std::vector<int> truth_of(found_objects.size(), -1);  // the scene object a reported one was matched to
    s.reported += static_cast<int>(found_objects.size());
    for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi) {
      if (rs.catalog_index[oi] < 0) continue;  // the distractor box
      const auto& obj = rs.scene.objects[oi];
      const auto& truth = library.models[static_cast<std::size_t>(rs.catalog_index[oi])];
      const fs::Vec3 centre_true = obj.rotation * truth.center + obj.translation;
      ++s.objects;
      // Nearest reported object (by model centre) decides the identity; a hit needs the same model within 10
      // mm.
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
      const bool stacked = rs.support[oi] >= 0;
      s.stacked += stacked ? 1 : 0;
      int faces_seen = 0;
      std::size_t object_cells = 0;
      for (const std::size_t n : face_cells[oi + 1]) {
        faces_seen += n >= kSeenFaceCells ? 1 : 0;
        object_cells += n;
      }
      s.seen3 += faces_seen >= 3 ? 1 : 0;
      if (hit >= 0) {
        used[static_cast<std::size_t>(hit)] = true;
        truth_of[static_cast<std::size_t>(hit)] = static_cast<int>(oi);
        ++s.found;
        s.stacked_found += stacked ? 1 : 0;
        s.seen3_found += faces_seen >= 3 ? 1 : 0;
        const auto& h = found_objects[static_cast<std::size_t>(hit)];
        s.rot_err.push_back(fs::host::rec::rotation_angle_deg_sym(obj.rotation, h.R, truth));
        s.trans_err.push_back(hit_d);
      } else {
        ++missed_models[truth.name];
        std::string got = "nothing";
        if (any >= 0) {
          const auto& h = found_objects[static_cast<std::size_t>(any)];
          got = library.models[static_cast<std::size_t>(h.model)].name + " at " + std::to_string(any_d) +
                " mm, " + std::to_string(fs::host::rec::rotation_angle_deg_sym(obj.rotation, h.R, truth)) +
                " deg";
        }
        if (nearest >= 0) {
          const auto& h = found_objects[static_cast<std::size_t>(nearest)];
          if (h.model != rs.catalog_index[oi]) {
            bool listed = false;
            for (const auto& a : h.listed_alternatives()) listed = listed || a.model == rs.catalog_index[oi];
            ++s.confusions[truth.name + " -> " + library.models[static_cast<std::size_t>(h.model)].name +
                           (listed ? " *" : "")];
            if (listed) {
              ++s.truth_is_alternative;
              got += " (true model listed as an alternative)";
            }
          }
        }
        // The truth in its true pose and the nearest report in its own, on the fine samples: a truth that
        // fits at least as well (as many inliers within 2, no more violations) was lost by the pipeline, not
        // by the view.
        const auto truth_fit = verify_on_fine(truth, obj.rotation, obj.translation);
        std::string fits =
            "truth in " + std::to_string(truth_fit.inliers) + " viol " + std::to_string(truth_fit.violations);
        bool lost = true;
        if (nearest >= 0) {
          const auto& h = found_objects[static_cast<std::size_t>(nearest)];
          const auto rep = verify_on_fine(library.models[static_cast<std::size_t>(h.model)], h.R, h.t);
          fits += ", reported in " + std::to_string(rep.inliers) + " viol " + std::to_string(rep.violations);
          lost = truth_fit.inliers + 2 >= rep.inliers && truth_fit.violations <= rep.violations;
        }
        if (faces_seen >= 3 && nearest < 0) ++s.seen3_unreported;
        if (faces_seen >= 3 && nearest >= 0 && lost) ++s.seen3_truth_fits;
        if (args.verbose)
          std::printf(
              "MISS seed %llu %s: %s (face %d on %s, %d faces, %d seen, %zu points) -> nearest %s; %s; note: "
              "%s\n",
              static_cast<unsigned long long>(seed), fs::sim::to_string(cat), truth.name.c_str(),
              rs.resting_face[oi],
              stacked ? rs.scene.objects[static_cast<std::size_t>(rs.support[oi])].name.c_str() : "table",
              static_cast<int>(truth.faces.size()), faces_seen, object_cells, got.c_str(), fits.c_str(),
              note.c_str());
      }
    }
    // A physically possible answer: no two reported solids interpenetrate.
    for (std::size_t a = 0; a < found_objects.size(); ++a)
      for (std::size_t b = a + 1; b < found_objects.size(); ++b) {
        const auto& oa = found_objects[a];
        const auto& ob = found_objects[b];
        const auto ip = fs::host::rec::interpenetration(
            fs::host::rec::ModelGeometry(library.models[static_cast<std::size_t>(oa.model)]), oa.R, oa.t,
            fs::host::rec::ModelGeometry(library.models[static_cast<std::size_t>(ob.model)]), ob.R, ob.t);
        if (ip.depth_mm > args.params.interpenetration_mm &&
            ip.volume_share > args.params.interpenetration_share) {
          ++s.interpenetrating_pairs;
          std::printf("INTERPENETRATING seed %llu: objects %zu and %zu (%.1f %%, %.1f mm)\n",
                      static_cast<unsigned long long>(seed), a, b, 100 * ip.volume_share, ip.depth_mm);
        }
      }
    // Reported object h lists scene object oi's true model as an alternative, in its own pose (a candidate of
    // another shape sits elsewhere on the same visible faces), centre within 10 mm of the truth.
    auto lists_truth = [&](const fs::host::rec::Hypothesis& h, std::size_t oi) {
      const int model = rs.catalog_index[oi];
      const auto& obj = rs.scene.objects[oi];
      const auto& tm = library.models[static_cast<std::size_t>(model)];
      const fs::Vec3 centre = obj.rotation * tm.center + obj.translation;
      for (const auto& a : h.listed_alternatives())
        if (a.model == model && (a.R * tm.center + a.t - centre).norm() < 10.0) return true;
      return false;
    };
    // Ambiguous reports: correct when the reported model is the true one (found: centre within 10 mm) or an
    // alternative is, in its own pose within 10 mm of the truth.
    for (std::size_t j = 0; j < found_objects.size(); ++j) {
      const auto& h = found_objects[j];
      if (h.listed_alternatives().empty()) continue;
      ++s.ambiguous;
      int truth = truth_of[j];
      if (truth < 0) {
        const auto& m = library.models[static_cast<std::size_t>(h.model)];
        double best = 20.0;
        for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi) {
          if (rs.catalog_index[oi] < 0) continue;
          const auto& obj = rs.scene.objects[oi];
          const auto& tm = library.models[static_cast<std::size_t>(rs.catalog_index[oi])];
          const double d = (h.R * m.center + h.t - (obj.rotation * tm.center + obj.translation)).norm();
          if (d < best) best = d, truth = static_cast<int>(oi);
        }
      }
      if (truth < 0) continue;
      const bool correct =
          (truth_of[j] >= 0 && h.model == rs.catalog_index[static_cast<std::size_t>(truth)]) ||
          lists_truth(h, static_cast<std::size_t>(truth));
      s.ambiguous_correct += correct ? 1 : 0;
    }
    // Missed objects whose true model is a candidate of an unmatched ambiguous report within 10 mm.
    std::vector<bool> as_candidate(found_objects.size(), false);
    for (std::size_t oi = 0; oi < rs.scene.objects.size(); ++oi) {
      if (rs.catalog_index[oi] < 0) continue;
      bool matched = false;
      for (std::size_t j = 0; j < found_objects.size(); ++j)
        matched = matched || (truth_of[j] == static_cast<int>(oi));
      if (matched) continue;
      for (std::size_t j = 0; j < found_objects.size(); ++j) {
        if (used[j] || as_candidate[j] || !lists_truth(found_objects[j], oi)) continue;
        as_candidate[j] = true;
        ++s.found_as_candidate;
        break;
      }
    }
    int extra = 0;
    for (std::size_t j = 0; j < found_objects.size(); ++j) extra += used[j] ? 0 : 1;
    for (std::size_t j = 0; j < found_objects.size(); ++j) {
      const auto& h = found_objects[j];
      std::size_t bin = 0;
      while (bin + 1 < kConfidenceBins.size() && h.confidence() >= kConfidenceBins[bin + 1]) ++bin;
      auto& row = (used[j] || as_candidate[j] ? s.conf_correct : s.conf_false)[h.level >= 3 ? 1 : 0];
      ++row[bin];
    }
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

  std::printf(
      "\n%d scenes, %s rig, %u steps, depth noise %.2f mm, dropout %.3f, sizes %.0f-%.0f mm%s, threads %d, "
      "seed %llu, %.0f s total\n\n",
      args.scenes, args.rig.c_str(), args.steps, args.noise, args.dropout, args.sizes[0], args.sizes[1],
      args.as_cloud ? ", as clouds (no calibration, table found)" : "", args.params.threads,
      static_cast<unsigned long long>(args.seed),
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  std::printf(
      "| category | scenes | objects | found (model + centre < 10 mm) | top-1 identity "
      "| rot err median / p90 (deg) | centre err median / p90 (mm) | reported "
      "| false positives (%% of reported) | scenes with a false positive | ambiguous (correct) "
      "| CPU ms median / p90 | wall ms median / p90 | allocs of a warm recognize (median / max) |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  auto pct = [](int a, int b) { return b > 0 ? 100.0 * a / b : std::nan(""); };
  for (const auto& [cat, s] : stats)
    std::printf(
        "| %s | %d | %d | %d (%.1f %%) | %.1f %% | %.2f / %.2f | %.2f / %.2f | %d | %d (%.1f %%) "
        "| %d (%.1f %%) | %d (%d) | %.0f / %.0f | %.0f / %.0f | %.0f / %.0f |\n",
        fs::sim::to_string(cat), s.scenes, s.objects, s.found, pct(s.found, s.objects),
        pct(s.identity_ok, s.objects), quantile(s.rot_err, 0.5), quantile(s.rot_err, 0.9),
        quantile(s.trans_err, 0.5), quantile(s.trans_err, 0.9), s.reported, s.extra, pct(s.extra, s.reported),
        s.scenes_with_fp, pct(s.scenes_with_fp, s.scenes), s.ambiguous, s.ambiguous_correct,
        quantile(s.cpu, 0.5), quantile(s.cpu, 0.9), quantile(s.wall, 0.5), quantile(s.wall, 0.9),
        quantile(s.allocs, 0.5), quantile(s.allocs, 1.0));
  for (const auto& [cat, s] : stats)
    if (s.stacked > 0)
      std::printf(
          "\n%s: found %d of %d objects on the table (%.1f %%), %d of %d resting on another object (%.1f "
          "%%)\n",
          fs::sim::to_string(cat), s.found - s.stacked_found, s.objects - s.stacked,
          pct(s.found - s.stacked_found, s.objects - s.stacked), s.stacked_found, s.stacked,
          pct(s.stacked_found, s.stacked));
  std::printf("\nobjects seen with 3 faces or more (%zu measured cells each), found (model + centre):\n",
              kSeenFaceCells);
  for (const auto& [cat, s] : stats)
    std::printf(
        "  %-10s %d of %d (%.1f %%); of the %d missed, %d have no report within 20 mm and %d fit the view in "
        "their true pose at least as well as the report there; of the %d others %d\n",
        fs::sim::to_string(cat), s.seen3_found, s.seen3, pct(s.seen3_found, s.seen3), s.seen3 - s.seen3_found,
        s.seen3_unreported, s.seen3_truth_fits, s.objects - s.seen3, s.found - s.seen3_found);
  std::printf(
      "\nambiguous: reported objects that list alternatives; correct: the true model is the reported one or "
      "listed\n");
  std::printf(
      "\nscored as issue #20 asks (an ambiguous report is correct when the true model is among its "
      "candidates):\n");
  for (const auto& [cat, s] : stats)
    std::printf("  %-10s found %d of %d (%.1f %%), false positives %d of %d reported (%.1f %%)\n",
                fs::sim::to_string(cat), s.found + s.found_as_candidate, s.objects,
                pct(s.found + s.found_as_candidate, s.objects), s.extra - s.found_as_candidate, s.reported,
                pct(s.extra - s.found_as_candidate, s.reported));
  std::printf(
      "\nreported objects by confidence, correct / false (issue #20's scoring), their search matching 2 "
      "faces "
      "or fewer | 3 or more:\n");
  for (const auto& [cat, s] : stats) {
    std::printf("  %-10s", fs::sim::to_string(cat));
    for (std::size_t b = 0; b < kConfidenceBins.size(); ++b) {
      if (b == 0)
        std::printf(" <%.2f:", kConfidenceBins[1]);
      else if (b + 1 < kConfidenceBins.size())
        std::printf(" %.2f-%.2f:", kConfidenceBins[b], kConfidenceBins[b + 1]);
      else
        std::printf(" >=%.2f:", kConfidenceBins[b]);
      std::printf(" %d / %d | %d / %d;", s.conf_correct[0][b], s.conf_false[0][b], s.conf_correct[1][b],
                  s.conf_false[1][b]);
    }
    std::printf("\n");
  }
  std::printf("\nwall time per stage (median ms; stages run on --threads workers): \n");
  for (const auto& [cat, s] : stats)
    std::printf(
        "  %-10s segmentation + PFRG %.1f, matching %.1f, hypotheses + verification %.1f; every other row "
        "segmented in %d of %zu scans\n",
        fs::sim::to_string(cat), quantile(s.seg_ms, 0.5), quantile(s.match_ms, 0.5),
        quantile(s.verify_ms, 0.5), s.thinned, s.seg_ms.size());
  if (!missed_models.empty()) {
    std::printf("\nmissed models (count):");
    for (const auto& [name, n] : missed_models) std::printf(" %s:%d", name.c_str(), n);
    std::printf("\n");
  }
  std::printf(
      "confusions per category (true model -> nearest reported model: count; * = the true model is "
      "listed as an alternative):\n");
  for (const auto& [cat, s] : stats) {
    int n_confusions = 0;
    for (const auto& c : s.confusions) n_confusions += c.second;
    std::printf("  %s: %d, %d with the true model listed%s", fs::sim::to_string(cat), n_confusions,
                s.truth_is_alternative, s.confusions.empty() ? "" : ":");
    for (const auto& [name, n] : s.confusions) std::printf(" %s: %d;", name.c_str(), n);
    std::printf("\n");
  }
  int interpenetrating = 0;
  for (const auto& [cat, s] : stats) interpenetrating += s.interpenetrating_pairs;
  std::printf("interpenetrating pairs of reported objects: %d\n", interpenetrating);
  return interpenetrating > 0 ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_recognition: the recognition benchmark"};
  try {
    return run(parse_args(app, argc, argv));
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_recognition: %s\n", e.what());
    return 2;
  }
}
