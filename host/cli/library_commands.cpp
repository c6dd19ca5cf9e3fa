// facetscan library build|merge|list|show|polycubes
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common/error.hpp"
#include "common/mesh.hpp"
#include "host/cli/commands.hpp"
#include "host/cli/progress.hpp"
#include "host/library/library.hpp"
#include "host/library/library_merge.hpp"
#include "host/library/mesh_files.hpp"
#include "host/library/polycubes.hpp"
#include "host/library/views.hpp"
#include "host/match/node_set.hpp"
#include "host/pfrg/pfrg.hpp"

#include <nlohmann/json.hpp>

namespace fs::host::cli {
namespace {

namespace stdfs = std::filesystem;

void print_table(const Library& lib) {
  std::size_t w = 5;
  for (const auto& m : lib.models) w = std::max(w, m.name.size());
  fmt::print("{:<{}}  {:>5}  {:>5}  {:>14}  {:>14}  {:>8}\n", "model", w, "faces", "arcs", "area_mm2",
             "volume_mm3", "symmetry");
  for (const auto& m : lib.models)
    fmt::print("{:<{}}  {:>5}  {:>5}  {:>14.3f}  {:>14.3f}  {:>8}{}\n", m.name, w, m.face_count(),
               m.arc_count(), m.total_area, m.volume, m.symmetry_order(),
               m.open ? "  (open: faces may be missing)" : "");
  fmt::print("{} models\n", lib.models.size());
}

}  // namespace

void add_library_commands(CLI::App& app) {
  auto* lib = app.add_subcommand("library",
                                 "Reference model library: build from meshes, merge, list, show, polycubes");
  lib->require_subcommand(1);

  struct BuildArgs {
    std::vector<std::string> inputs;
    std::string out;
    BuildOptions options;
    bool quiet = false;
    bool allow_large = false;
  };
  auto b = std::make_shared<BuildArgs>();
  auto* build =
      lib->add_subcommand("build", "Build a .fslib from meshes (OFF, OBJ, STL, PLY) and directories of them");
  build->add_option("inputs", b->inputs, "Mesh files or directories")->required();
  build->add_option("-o,--output", b->out, "Output library (.fslib)")->required();
  build->add_option("--scale", b->options.scale, "Multiply coordinates (to millimetres)")
      ->check(CLI::PositiveNumber);
  build->add_option("--merge-angle", b->options.merge_angle_deg, "Coplanar merge tolerance (degrees)")
      ->check(CLI::Range(0.0, 30.0));
  build->add_flag("--allow-open", b->options.allow_open,
                  "Accept open meshes (flagged: faces may be missing)");
  build->add_flag("--allow-large", b->allow_large,
                  "Keep models of more faces than the matcher takes (a warning; they are never matched)");
  build->add_flag("-q,--quiet", b->quiet, "No progress bar, no table");
  build->callback([b] {
    const auto files = collect_mesh_files(b->inputs);
    Library out;
    Progress progress(files.size(), b->quiet);
    for (std::size_t i = 0; i < files.size(); ++i) {
      progress.update(i, files[i].filename().string());
      Mesh mesh = read_mesh(files[i]);
      mesh.name = files[i].stem().string();
      Model m = build_model(mesh, b->options, files[i].string());
      // A model the matcher cannot take would fail every scan matched against it: refused here, by default.
      if (m.face_count() > static_cast<std::size_t>(match::kMaxNodes)) {
        const std::string msg = fmt::format("{}: {} faces; the matcher takes models of at most {} faces",
                                            files[i].string(), m.face_count(), match::kMaxNodes);
        if (!b->allow_large) throw Error(msg + " (--allow-large keeps it)");
        std::fprintf(stderr, "facetscan library build: warning: %s\n", msg.c_str());
      }
      if (out.find(m.name))
        throw Error(fmt::format("{}: a model named '{}' is already in the library (names are file stems)",
                                files[i].string(), m.name));
      out.add(std::move(m));
    }
    progress.update(files.size(), "done");
    progress.finish();
    out.save(b->out);
    if (!b->quiet) {
      print_table(out);
      fmt::print("wrote {}\n", b->out);
    }
  });

  struct MergeArgs {
    std::vector<std::string> inputs;
    std::string out;
    BuildOptions options;
    bool quiet = false;
    bool allow_large = false;
  };
  auto mg = std::make_shared<MergeArgs>();
  auto* merge = lib->add_subcommand(
      "merge", "Write one .fslib of the models of several .fslib files and meshes / directories (in order)");
  merge->add_option("inputs", mg->inputs, ".fslib files, mesh files or directories of meshes")->required();
  merge->add_option("-o,--output", mg->out, "Output library (.fslib)")->required();
  merge->add_option("--scale", mg->options.scale, "Multiply mesh coordinates (to millimetres)")
      ->check(CLI::PositiveNumber);
  merge
      ->add_option("--merge-angle", mg->options.merge_angle_deg,
                   "Coplanar merge tolerance of meshes (degrees)")
      ->check(CLI::Range(0.0, 30.0));
  merge->add_flag("--allow-open", mg->options.allow_open,
                  "Accept open meshes (flagged: faces may be missing)");
  merge->add_flag("--allow-large", mg->allow_large,
                  "Keep models of more faces than the matcher takes (a warning; they are never matched)");
  merge->add_flag("-q,--quiet", mg->quiet, "No progress bar, no summary");
  merge->callback([mg] {
    Progress progress(0, mg->quiet);
    LibraryMerge merged =
        gather_library(mg->inputs, mg->options, [&](std::size_t i, std::size_t n, const std::string& name) {
          progress.set_total(n);
          progress.update(i, name);
        });
    progress.finish();
    if (merged.size() == 0) {
      std::string names;
      for (const auto& in : mg->inputs) names += (names.empty() ? "" : ", ") + in;
      throw Error(names + ": the library has no models");
    }
    // Sources in order with their model counts (.fslib files by name, meshes together).
    std::vector<std::pair<std::string, std::size_t>> counts;
    for (std::size_t i = 0; i < merged.size(); ++i) {
      const Model& m = merged.library().models[i];
      const std::string& src = merged.source_of(i);
      if (m.face_count() > static_cast<std::size_t>(match::kMaxNodes)) {
        const std::string msg =
            fmt::format("{}: model '{}' has {} faces; the matcher takes models of at most {} faces", src,
                        m.name, m.face_count(), match::kMaxNodes);
        if (!mg->allow_large) throw Error(msg + " (--allow-large keeps it)");
        std::fprintf(stderr, "facetscan library merge: warning: %s\n", msg.c_str());
      }
      const std::string key = is_library_file(src) ? src : std::string("meshes");
      if (counts.empty() || counts.back().first != key)
        counts.emplace_back(key, 1);
      else
        ++counts.back().second;
    }
    const Library out = merged.release();
    out.save(mg->out);
    if (!mg->quiet) {
      for (const auto& [src, n] : counts) fmt::print("{}: {} models\n", src, n);
      fmt::print("wrote {} models to {}\n", out.models.size(), mg->out);
    }
  });

  auto lib_path = std::make_shared<std::string>();
  auto* list =
      lib->add_subcommand("list", "List the models of a library (faces, arcs, area, symmetry order)");
  list->add_option("library", *lib_path, "Library file (.fslib)")->required();
  list->callback([lib_path] { print_table(Library::load(*lib_path)); });

  struct ShowArgs {
    std::string library, model, out = "-";
    std::vector<double> view;
  };
  auto s = std::make_shared<ShowArgs>();
  auto* show =
      lib->add_subcommand("show", "Print a model's PFRG as JSON (or the partial view from a direction)");
  show->add_option("library", s->library, "Library file (.fslib)")->required();
  show->add_option("model", s->model, "Model name")->required();
  show->add_option("--view", s->view,
                   "Viewing direction X Y Z (sensor -> object): the PFRG of the visible faces "
                   "plus a supernode")
      ->expected(3);
  show->add_option("-o,--output", s->out, "Output JSON file (- = stdout)");
  show->callback([s] {
    const Library l = Library::load(s->library);
    const Model* m = l.find(s->model);
    if (!m) throw Error(fmt::format("{}: no model named '{}'", s->library, s->model));
    Pfrg g = m->graph;
    if (!s->view.empty()) {
      const Vec3 dir(s->view[0], s->view[1], s->view[2]);
      if (!(dir.norm() > 0) || !dir.allFinite())
        throw Error("--view: the direction must be a non-zero vector");
      g = partial_view(*m, Mat3::Identity(), dir);
    }
    if (s->out == "-")
      fmt::print("{}\n", to_json(g).dump(1));
    else
      write_pfrg_json(g, s->out);
  });

  struct CubeArgs {
    int max_volume = 4;
    double edge = 20.0;
    std::string out;
    bool quiet = false;
  };
  auto c = std::make_shared<CubeArgs>();
  auto* cubes =
      lib->add_subcommand("polycubes", "Build all polycubes up to a volume (thesis ch. 4.1.3) as a .fslib");
  cubes->add_option("--max-volume", c->max_volume, "Largest number of unit cubes")
      ->required()
      ->check(CLI::Range(1, 10));
  cubes->add_option("--edge", c->edge, "Cube edge length (mm)")->check(CLI::PositiveNumber);
  cubes->add_option("-o,--output", c->out, "Output library (.fslib)")->required();
  cubes->add_flag("-q,--quiet", c->quiet, "No progress bar, no summary");
  cubes->callback([c] {
    const auto all = enumerate_polycubes(c->max_volume);
    std::size_t total = 0;
    for (const auto& v : all) total += v.size();
    Library out;
    Progress progress(total, c->quiet);
    for (Model& m : polycube_models(
             all, c->edge, [&](std::size_t done, const std::string&name) { progress.update(done, name); }))
      out.add(std::move(m));
    progress.update(total, "done");
    progress.finish();
    out.save(c->out);
    if (!c->quiet) {
      for (std::size_t v = 0; v < all.size(); ++v)
        fmt::print("volume {}: {} polycubes\n", v + 1, all[v].size());
      fmt::print("wrote {} models to {}\n", total, c->out);
    }
  });
}

}  // namespace fs::host::cli
