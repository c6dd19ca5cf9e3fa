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
  if (inputs.size() == 1 && stdfs::path(inputs[0]).extension() == ".fslib") return Library::load(inputs[0]);
  const auto files = collect_mesh_files(inputs);
  Library lib;
  for (std::size_t i = 0; i < files.size(); ++i) {
    if (progress) progress(i, files.size(), files[i].stem().string());
    lib.add(build_model(read_mesh(files[i]), options));
  }
  return lib;
}

}  // namespace fs::host
