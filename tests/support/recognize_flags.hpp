#pragma once
// Benchmark helper: the command-line options that set one RecognizeParams field each, shared by
// bench_recognition and bench_library_scale (left out, the recognizer's default stays). Matching scope
// (--no-arc-index, --all-roots, --no-second-search, ...), the hypothesis pool, the verification budget and
// the support test's look below a solid (--hidden-below-rays).
#include <CLI/CLI.hpp>

#include <cstdint>

#include "host/recognize/recognizer.hpp"

namespace fs::test {

inline void add_recognize_flags(CLI::App& app, fs::host::rec::RecognizeParams& p) {
  const auto at_least = [](int lo) { return CLI::Range(lo, 1 << 30); };
  app.add_option("--solutions", p.solutions_per_model,
                 "RecognizeParams::solutions_per_model (default 32): search solutions kept per reference")
      ->check(at_least(1));
  app.add_option(
         "--max-hypotheses", p.max_hypotheses,
         "RecognizeParams::max_hypotheses: search solutions kept per round, all references (default: 4 "
         "per reference, 8192 to 65536)")
      ->check(at_least(1));
  app.add_option(
         "--hidden-below-rays", p.hidden_below_min_rays,
         "RecognizeParams::hidden_below_min_rays (default 0): rays that must end in front of the space "
         "under a solid seen clearly for it to be held up")
      ->check(at_least(0));
  app.add_option("--slide-fine", p.verify.slide_fine_mm,
                 "VerifyParams::slide_fine_mm (default 0.0625): the finest step of the slide along a free "
                 "translation, on the fine samples; 0 = no fine steps")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--slide-range", p.verify.slide_range_mm,
                 "VerifyParams::slide_range_mm: how far the slide along a free translation goes each way")
      ->check(CLI::NonNegativeNumber);
  app.add_option(
         "--slide-keep-inliers", p.verify.slide_keep_inliers,
         "VerifyParams::slide_keep_inliers: the share of the inliers an offset of the slide must keep")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--table-snap", p.table_snap_mm,
                 "RecognizeParams::table_snap_mm (default 8): a pose free along a climbing direction is also "
                 "checked moved onto the table when its lowest point is this near it; 0 = off")
      ->check(CLI::NonNegativeNumber);
  app.add_option(
         "--alternative-slack", p.alternative_inlier_slack,
         "RecognizeParams::alternative_inlier_slack (default 3): an alternative may explain this many "
         "points fewer than 97 % of the object's")
      ->check(at_least(0));
  app.add_option("--support-own-plane", p.support_own_plane_mm,
                 "RecognizeParams::support_own_plane_mm (default 0.5): measured points this near one of a "
                 "solid's seen face planes do not hold it up; 0 = they do")
      ->check(CLI::NonNegativeNumber);
  app.add_flag(
      "--no-seen-fit", [&p](std::int64_t) { p.alternative_seen_fit = false; },
      "RecognizeParams::alternative_seen_fit off: alternatives compare confidences, occluded rays included");
  app.add_option("--max-states", p.max_states, "RecognizeParams::max_states: the state budget of one search")
      ->check(at_least(1));
  app.add_flag(
      "--no-arc-index", [&p](std::int64_t) { p.arc_index = false; },
      "match every reference (RecognizeParams::arc_index off)");
  app.add_flag(
      "--all-roots", [&p](std::int64_t) { p.symmetry_roots = false; },
      "start each search from every reference face (RecognizeParams::symmetry_roots off)");
  app.add_flag(
      "--no-second-search", [&p](std::int64_t) { p.second_search = false; },
      "search a part once per model (RecognizeParams::second_search off)");
  app.add_option("--second-search-states", p.second_search_states,
                 "RecognizeParams::second_search_states: the second search's state budget")
      ->check(at_least(1));
  app.add_option(
         "--second-search-min-level", p.second_search_min_level,
         "RecognizeParams::second_search_min_level: faces of a first solution that starts a second search")
      ->check(at_least(1));
  app.add_option(
         "--max-verified", p.max_verified,
         "RecognizeParams::max_verified (default 256): hypotheses checked against the cloud per round")
      ->check(at_least(1));
  app.add_option("--verify-per-face", p.verify_per_face,
                 "RecognizeParams::verify_per_face (default 64): a scene face's share of the checks")
      ->check(at_least(1));
  app.add_option("--max-screened", p.max_screened,
                 "RecognizeParams::max_screened (default 2048): hypotheses screened on sparse samples first, "
                 "0 = none")
      ->check(at_least(0));
  app.add_option("--screen-per-face", p.screen_per_face,
                 "RecognizeParams::screen_per_face (default 512): a scene face's share of the screening")
      ->check(at_least(1));
  app.add_flag("--no-check-all-that-fit{false}", p.check_all_that_fit,
               "RecognizeParams::check_all_that_fit off: verify_per_face holds when all hypotheses fit in "
               "max_verified");
  app.add_option("--max-refined", p.max_refined,
                 "RecognizeParams::max_refined (default 24): coarse-checked hypotheses refined by ICP")
      ->check(at_least(1));
  app.add_option("--refine-per-face", p.refine_per_face,
                 "RecognizeParams::refine_per_face (default 3): a scene face's share of the refinements")
      ->check(at_least(1));
  app.add_flag("--no-refine-models-first{false}", p.refine_models_first,
               "RecognizeParams::refine_models_first off: a face's refinements in the order of the coarse "
               "check alone");
  app.add_option(
      "--refine-wait-margin", p.refine_wait_margin,
      "RecognizeParams::refine_wait_margin (default 0.05): a second placement of a model waits for "
      "the other models' hypotheses down to this much lower coarse confidence");
  app.add_option(
      "--refine-again-margin", p.refine_again_margin,
      "RecognizeParams::refine_again_margin (default 0.05): a second refinement for a face whose "
      "refined hypotheses all failed, among those within this coarse confidence of its best; < 0 = "
      "none");
  app.add_option("--inlier-weight", p.inlier_weight,
                 "RecognizeParams::inlier_weight (default 0.2): the ordering key's weight of the inliers")
      ->check(CLI::NonNegativeNumber);
  app.add_option(
         "--confidence-weight", p.confidence_weight,
         "RecognizeParams::confidence_weight (default 0.2): the ordering key's weight of the confidence")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--placement-rms", p.placement.rms_mm,
                 "RecognizeParams::placement.rms_mm (default 3): solutions whose matched planes disagree on "
                 "the translation by more go after the others of their search; <= 0 = the matcher's order");
  app.add_option("--placement-outside", p.placement.outside_mm,
                 "RecognizeParams::placement.outside_mm (default 5): ... or whose scene face lies farther "
                 "outside its posed model face");
  app.add_option("--rounds", p.rounds, "RecognizeParams::rounds (default 3): matching + verification rounds")
      ->check(CLI::Range(1, 100));
}

}  // namespace fs::test
