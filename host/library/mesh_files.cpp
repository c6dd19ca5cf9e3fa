#include "host/library/mesh_files.hpp"

#include <algorithm>
#include <cctype>

#include "common/error.hpp"
#include "common/file_list.hpp"
#include "common/mesh.hpp"

namespace fs::host {

namespace stdfs = std::filesystem;

bool is_mesh_file(const stdfs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".off" || ext == ".obj" || ext == ".stl" || ext == ".ply";
}

std::vector<stdfs::path> collect_mesh_files(const std::vector<std::string>& inputs) {
  return collect_files(inputs, is_mesh_file, ".off/.obj/.stl/.ply meshes");
}

Library load_or_build_library(
    const std::vector<std::string>& inputs, const BuildOptions& options,
    const std::function<void(std::size_t, std::size_t, const std::string&)>& progress) {
  Library lib;
  if (inputs.size() == 1 && stdfs::path(inputs[0]).extension() == ".fslib") {
    lib = Library::load(inputs[0]);
  } else {
    const auto files = collect_mesh_files(inputs);
    for (std::size_t i = 0; i < files.size(); ++i) {
      if (progress) progress(i, files.size(), files[i].stem().string());
      Model m = build_model(read_mesh(files[i]), options, files[i].string());
      if (lib.find(m.name))
        throw Error(files[i].string() + ": a model named '" + m.name +
                    "' is already in the library (names are file stems)");
      lib.add(std::move(m));
    }
  }
  if (lib.models.empty()) {
    std::string names;
    for (const auto& in : inputs) names += (names.empty() ? "" : ", ") + in;
    throw Error((names.empty() ? std::string("library") : names) + ": the library has no models");
  }
  return lib;
}

}  // namespace fs::host
