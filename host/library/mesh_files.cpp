#include "host/library/mesh_files.hpp"

#include <algorithm>
#include <cctype>

#include <fmt/format.h>

#include "common/error.hpp"
#include "common/file_list.hpp"
#include "common/mesh.hpp"

namespace fs::host {

namespace stdfs = std::filesystem;

namespace {

std::string lower_extension(const stdfs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

// One step of gathering: a .fslib file or a mesh file.
struct Step {
  stdfs::path path;
  bool library = false;
};

std::vector<Step> plan(const std::vector<std::string>& inputs) {
  std::vector<Step> steps;
  std::vector<std::pair<stdfs::path, std::string>> seen;  // canonical path, as named
  for (const auto& in : inputs) {
    const stdfs::path p(in);
    std::error_code ec;
    const stdfs::path canon = stdfs::weakly_canonical(p, ec);
    for (const auto& [c, name] : seen)
      if (!ec && c == canon)
        throw Error(in == name
                        ? fmt::format("{}: named twice among the library inputs", in)
                        : fmt::format("{}: named twice among the library inputs (also as {})", in, name));
    if (!ec) seen.emplace_back(canon, in);
    if (!stdfs::is_directory(p) && stdfs::exists(p) && !is_library_file(p) && !is_mesh_file(p))
      throw Error(
          fmt::format("{}: neither a model library (.fslib) nor a mesh (.off, .obj, .stl, .ply) nor a "
                      "directory of meshes",
                      in));
    if (is_library_file(p) && !stdfs::is_directory(p)) {
      if (!stdfs::exists(p)) throw Error(in + ": no such file or directory");
      steps.push_back({p, true});
      continue;
    }
    for (auto& f : collect_mesh_files({in})) steps.push_back({std::move(f), false});
  }
  return steps;
}

}  // namespace

bool is_mesh_file(const stdfs::path& p) {
  const std::string ext = lower_extension(p);
  return ext == ".off" || ext == ".obj" || ext == ".stl" || ext == ".ply";
}

bool is_library_file(const stdfs::path& p) { return lower_extension(p) == ".fslib"; }

std::vector<stdfs::path> collect_mesh_files(const std::vector<std::string>& inputs) {
  return collect_files(inputs, is_mesh_file, ".off/.obj/.stl/.ply meshes");
}

LibraryMerge gather_library(const std::vector<std::string>& inputs, const BuildOptions& options,
                            const LibraryProgress& progress) {
  const std::vector<Step> steps = plan(inputs);
  LibraryMerge merge;
  for (std::size_t i = 0; i < steps.size(); ++i) {
    const Step& s = steps[i];
    if (progress) progress(i, steps.size(), s.library ? s.path.filename().string() : s.path.stem().string());
    if (s.library)
      merge.add_all(Library::load(s.path), s.path.string());
    else
      merge.add(build_model(read_mesh(s.path), options, s.path.string()), s.path.string());
  }
  return merge;
}

Library load_or_build_library(const std::vector<std::string>& inputs, const BuildOptions& options,
                              const LibraryProgress& progress) {
  Library lib = gather_library(inputs, options, progress).release();
  if (lib.models.empty()) {
    std::string names;
    for (const auto& in : inputs) names += (names.empty() ? "" : ", ") + in;
    throw Error((names.empty() ? std::string("library") : names) + ": the library has no models");
  }
  return lib;
}

}  // namespace fs::host
