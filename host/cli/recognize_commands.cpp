// facetscan recognize | serve | demo
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/error.hpp"
#include "common/file_list.hpp"
#include "host/cli/commands.hpp"
#include "host/cli/fleet_submit.hpp"
#include "host/cli/live_commands.hpp"
#include "host/cli/memory_budget.hpp"
#include "host/cli/progress.hpp"
#include "host/io/load.hpp"
#include "host/library/mesh_files.hpp"
#include "host/match/params.hpp"
#include "host/pfrg/pfrg.hpp"
#include "host/recognize/recognizer.hpp"
#include "host/recognize/report.hpp"
#include "host/web/report_view.hpp"

namespace fs::host::cli {
namespace {

namespace stdfs = std::filesystem;

struct RecognizeOptions {
  std::vector<std::string> inputs;
  std::vector<std::string> library;
  std::string json_out;
  std::string report_dir;
  std::string params = "t9.3";
  std::string segment = "auto";
  std::string summary_csv;
  std::string summary_json;
  double min_confidence = -1.0;
  long long max_solutions = -1;
  double scale = 0.0;
  std::string memory_budget;  // --memory-budget (empty = default)
  int segment_row_step = 1;   // --segment-row-step
  int threads = 0;
  bool quiet = false;
  SubmitCli fleet;  // --nats: the fleet recognizes (fleet_submit.hpp)
};

// recognize --nats: the batch goes to the fleet (as `facetscan submit --wait`): workers recognize with their
// library; the local options that shape recognition or its files do not apply.
void run_recognize_on_fleet(const RecognizeOptions& o, const CLI::App& cmd) {
  for (const char* local : {"--library", "--json", "--report", "--params", "--segment", "--min-confidence",
                            "--scale", "--threads", "--memory-budget", "--segment-row-step",
                            "--max-solutions", "--summary-csv", "--summary-json"})
    if (cmd.count(local) > 0)
      throw Error(
          fmt::format("recognize --nats: {} is not used (the fleet's workers recognize with their own "
                      "library and parameters; `facetscan results --json` gives the result JSON)",
                      local));
  SubmitCli s = o.fleet;
  s.inputs = o.inputs;
  s.wait = true;
  s.quiet = o.quiet;
  run_submit(s);
}

bool is_input_file(const stdfs::path& p) {
  const std::string e = p.extension().string();
  return e == ".fscan" || e == ".pcd" || e == ".ply";
}

std::vector<stdfs::path> collect_inputs(const std::vector<std::string>& inputs) {
  return collect_files(inputs, is_input_file, ".fscan/.pcd/.ply files");
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string o = "\"";
  for (char c : s) o += c == '"' ? std::string("\"\"") : std::string(1, c);
  return o + "\"";
}

void write_file(const std::string& path, const std::string& text) {
  if (path == "-") {
    std::fwrite(text.data(), 1, text.size(), stdout);
    return;
  }
  std::ofstream f(path, std::ios::binary);
  f << text;
  if (!f) throw Error(path + ": cannot write");
}

void run_recognize(const RecognizeOptions& o) {
  const auto files = collect_inputs(o.inputs);
  Progress lib_progress(0, o.quiet);
  const Library library =
      load_or_build_library(o.library, {}, [&](std::size_t i, std::size_t n, const std::string& name) {
        lib_progress.set_total(n);
        lib_progress.update(i, "model " + name);
      });
  lib_progress.finish();
  if (library.models.empty()) throw Error("the library has no models");

  rec::RecognizeParams params;
  params.match = match::read_params(o.params);
  params.threads = o.threads;
  params.segment_row_step = o.segment_row_step;
  if (o.min_confidence >= 0) params.min_confidence = o.min_confidence;
  if (o.max_solutions >= 0) params.max_solutions = o.max_solutions;

  // One recognizer per segmentation profile, sized by the largest input (warm for every further scan).
  std::unique_ptr<rec::Recognizer> recognizer;
  std::string recognizer_profile;
  OrganizedCloud cloud;
  LoadOptions lo;
  lo.scale = o.scale;
  lo.limits = memory_budget_limits(o.memory_budget, o.threads, o.segment_row_step);
  // A directory is a batch even when it holds one input (its summary tables are written as for more).
  bool any_directory = false;
  for (const auto& in : o.inputs) any_directory = any_directory || stdfs::is_directory(in);
  const bool batch = files.size() > 1 || any_directory;
  Progress progress(files.size(), o.quiet || !batch);
  nlohmann::json summary = nlohmann::json::array();
  std::string csv = "file,status,objects,models,confidences,total_ms,note\n";
  nlohmann::json last_json;
  for (std::size_t i = 0; i < files.size(); ++i) {
    const std::string path = files[i].string();
    progress.update(i, files[i].filename().string());
    nlohmann::json row = {{"file", path}};
    try {
      const LoadInfo info = load_cloud(path, cloud, lo);
      std::string profile = o.segment;
      if (profile == "auto")
        profile = segment_profile_for(info);  // laser for scans and mm clouds, kinect for metres
      if (!recognizer || profile != recognizer_profile) {
        if (!seg::SegmentParams::by_name(profile, params.segment))
          throw Error("--segment: unknown profile '" + profile + "' (laser, kinect, auto)");
        recognizer =
            std::make_unique<rec::Recognizer>(library, params, std::max<std::size_t>(cloud.points.size(), 1));
        recognizer_profile = profile;
      }
      const rec::Recognition& r = recognizer->recognize(cloud);
      if (std::getenv("FACETSCAN_DEBUG")) {
        std::fprintf(stderr, "scene graph: %s\n", to_json(recognizer->scene_graph()).dump().c_str());
        for (const rec::Hypothesis* h : recognizer->candidates()) {
          std::string m;
          for (const auto& fm : h->matches)
            m += fmt::format(" {}:{}{}", fm.scene, fm.ref, fm.expanded ? "e" : "");
          std::fprintf(stderr,
                       "candidate %-20s cost %.5f conf %.3f inl %d viol %d occ %d t (%.1f %.1f %.1f) [%s]\n",
                       library.models[static_cast<std::size_t>(h->model)].name.c_str(), h->cost,
                       h->verify.confidence, h->verify.inliers, h->verify.violations, h->verify.occluded,
                       h->t.x(), h->t.y(), h->t.z(), m.c_str());
        }
        if (std::string(std::getenv("FACETSCAN_DEBUG")) == "2")
          for (const rec::Hypothesis* h : recognizer->all_hypotheses()) {
            std::string m;
            for (const auto& fm : h->matches)
              m += fmt::format(" {}:{}{}", fm.scene, fm.ref, fm.expanded ? "e" : "");
            std::fprintf(stderr,
                         "hypothesis %-20s level %d prescore %.3f cost %.5f conf %.3f support %.1f [%s]\n",
                         library.models[static_cast<std::size_t>(h->model)].name.c_str(), h->level,
                         h->prescore, h->cost, h->verify.confidence, h->verify.support, m.c_str());
          }
      }
      nlohmann::json j = rec::to_json(r, library);
      j["input"] = {{"file", path},
                    {"format", info.format},
                    {"width", cloud.width},
                    {"height", cloud.height},
                    {"valid_points", info.valid_points},
                    {"complete_scan", info.complete_scan}};
      if (!info.complete_scan) j["input"]["scan_status"] = info.scan_status;
      if (info.format == "fscan") {
        j["input"]["stripe_points"] = info.stripe_points;
        j["input"]["shared_cell"] = info.triangulation.shared_cell;
        j["input"]["stripes_over_budget"] = info.stripes_over_budget;
      }
      if (!batch && !o.quiet) {
        if (!info.complete_scan) fmt::print("note: partial scan ({})\n", info.scan_status);
        if (info.stripes_over_budget > 0)
          fmt::print(
              "note: {} stripe(s) refused: their points exceed the memory budget of {} (--memory-budget)\n",
              info.stripes_over_budget, format_byte_size(lo.limits.budget_bytes));
        if (info.triangulation.shared_cell > 0)
          fmt::print(
              "note: {} of {} stripe points shared an image row with a brighter point of the same stripe "
              "(one point per row and step is kept)\n",
              info.triangulation.shared_cell, info.stripe_points);
        fmt::print("{}", rec::result_table(r, library));
      }
      if (!o.report_dir.empty()) {
        const stdfs::path dir =
            batch ? stdfs::path(o.report_dir) / files[i].stem() : stdfs::path(o.report_dir);
        web::write_report(dir, files[i].filename().string(), cloud, *recognizer, r, recognizer->table());
        if (!batch && !o.quiet) fmt::print("report: {}\n", (dir / "index.html").string());
      }
      std::string models, confs;
      for (const auto& obj : j["objects"]) {
        models += (models.empty() ? "" : ";") + obj["model"].get<std::string>();
        confs += (confs.empty() ? "" : ";") + fmt::format("{:.2f}", obj["confidence"].get<double>());
      }
      row["status"] = "ok";
      row["objects"] = j["objects"].size();
      row["models"] = models;
      row["total_ms"] = r.stats.total_ms;
      row["note"] = r.note;
      csv += fmt::format("{},ok,{},{},{},{:.1f},{}\n", csv_field(path), j["objects"].size(),
                         csv_field(models), confs, r.stats.total_ms, csv_field(r.note));
      last_json = std::move(j);
      if (batch) row["result"] = last_json;
    } catch (const Error& e) {
      // Errors of the stages after loading (segmentation, matching) name the input too.
      const std::string what = e.what();
      if (!batch) {
        if (what.rfind(path, 0) == 0) throw;
        throw Error(path + ": " + what);
      }
      row["status"] = "error";
      row["note"] = e.what();
      csv += fmt::format("{},error,0,,,0,{}\n", csv_field(path), csv_field(e.what()));
    }
    summary.push_back(std::move(row));
  }
  progress.update(files.size(), "done");
  progress.finish();
  if (batch) {
    if (!o.quiet) {
      fmt::print("{:<40} {:>7} {:>8}  {}\n", "file", "objects", "ms", "models");
      for (const auto& row : summary)
        fmt::print("{:<40} {:>7} {:>8.1f}  {}\n",
                   stdfs::path(row["file"].get<std::string>()).filename().string(), row.value("objects", 0),
                   row.value("total_ms", 0.0),
                   row["status"] == "ok" ? row.value("models", std::string())
                                         : "error: " + row.value("note", std::string()));
    }
    if (!o.summary_csv.empty()) write_file(o.summary_csv, csv);
    if (!o.summary_json.empty()) write_file(o.summary_json, summary.dump(2) + "\n");
    if (!o.json_out.empty()) write_file(o.json_out, summary.dump(2) + "\n");
  } else if (!o.json_out.empty()) {
    write_file(o.json_out, last_json.dump(2) + "\n");
  }
}

}  // namespace

void add_recognize_commands(CLI::App& app) {
  auto o = std::make_shared<RecognizeOptions>();
  auto* rc =
      app.add_subcommand("recognize",
                         "Recognize the library's objects in scans (.fscan) or point clouds (.pcd, .ply); "
                         "a directory is a batch");
  rc->add_option("inputs", o->inputs, "Input files or directories")->required();
  rc->add_option(
        "-l,--library", o->library,
        "Library: .fslib files, mesh files and directories of meshes, mixed (required, except with --nats)")
      ->expected(1, -1);
  rc->add_option("--json", o->json_out, "Write the recognition JSON to FILE ('-' = stdout)");
  rc->add_option("--report", o->report_dir,
                 "Write an HTML report into DIR (a sub-directory per input in a batch)");
  rc->add_option("--params", o->params, "Match parameters: a preset (t9.3, t7.34, ...) or a JSON file");
  rc->add_option("--segment", o->segment,
                 "Segmentation profile: auto (laser for .fscan and clouds in mm, kinect for clouds in "
                 "metres), laser, kinect");
  rc->add_option("--min-confidence", o->min_confidence, "Verification confidence an object needs (0..1)")
      ->check(CLI::Range(0.0, 1.0));
  rc->add_option("--scale", o->scale, "PCD/PLY: millimetres per file unit (default: auto)");
  rc->add_option("--threads", o->threads, "Matching threads (0 = all cores)");
  add_memory_budget_option(rc, o->memory_budget);
  add_segment_row_step_option(rc, o->segment_row_step);
  rc->add_option(
        "--max-solutions", o->max_solutions,
        "Stop each search after N solutions (TH_solutions; default 1, 0 = the match parameters' own)")
      ->check(CLI::NonNegativeNumber);
  rc->add_option("--summary-csv", o->summary_csv, "Batch: summary table as CSV");
  rc->add_option("--summary-json", o->summary_json, "Batch: summary as JSON");
  rc->add_flag("-q,--quiet", o->quiet, "No table, no progress bar");
  add_nats_options(rc, o->fleet.nats, false);
  rc->add_option("--scanner", o->fleet.scanner,
                 "--nats: scanner id of the submitted scans (subject facetscan.scans.ID)")
      ->capture_default_str();
  rc->add_option("--timeout", o->fleet.timeout_s, "--nats: give up after this many seconds (0 = never)");
  rc->callback([o, rc] {
    if (!o->fleet.nats.url.empty()) return run_recognize_on_fleet(*o, *rc);
    if (o->library.empty())
      throw Error("recognize: --library is required (or --nats URL: the fleet recognizes)");
    run_recognize(*o);
  });
  add_live_commands(app);
}

}  // namespace fs::host::cli
