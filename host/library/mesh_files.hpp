#pragma once
// Mesh files named on a command line: files and directories of .off/.obj/.stl/.ply (sorted), and a library
// built from them, or loaded when the single argument is a .fslib file.
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "host/library/library.hpp"

namespace fs::host {

bool is_mesh_file(const std::filesystem::path& p);
// Throws fs::Error for a missing path or a directory without meshes.
std::vector<std::filesystem::path> collect_mesh_files(const std::vector<std::string>& inputs);

// One .fslib file -> Library::load; otherwise meshes / directories -> build_model for each (progress(i, name)
// is called before each model). A library without models is an error naming the inputs
// ("lib.fslib: the library has no models"); mesh errors name the mesh file's path.
Library load_or_build_library(
    const std::vector<std::string>& inputs, const BuildOptions& options = {},
    const std::function<void(std::size_t, std::size_t, const std::string&)>& progress = {});

}  // namespace fs::host
