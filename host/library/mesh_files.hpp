#pragma once
// Library inputs named on a command line (`-l`, `library merge`): .fslib files, mesh files
// (.off/.obj/.stl/.ply) and directories of meshes (sorted), in any mix and number. The library holds their
// models in the order of the inputs; a model name that two inputs give is an error naming both
// (library_merge.hpp).
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "host/library/library.hpp"
#include "host/library/library_merge.hpp"

namespace fs::host {

bool is_mesh_file(const std::filesystem::path& p);
bool is_library_file(const std::filesystem::path& p);  // extension .fslib (any case)
// Throws fs::Error for a missing path or a directory without meshes.
std::vector<std::filesystem::path> collect_mesh_files(const std::vector<std::string>& inputs);

// progress(i, n, name) is called before each of the n steps: a .fslib file (name = its file name) or a mesh
// (name = the model's name).
using LibraryProgress = std::function<void(std::size_t, std::size_t, const std::string&)>;

// Every input checked first (exists; a file is a .fslib or a mesh; a directory holds meshes; no path named
// twice), then .fslib files loaded (Library::load) and meshes built (build_model). Errors name the file: a
// mesh error its whole path, a duplicate model both sources.
LibraryMerge gather_library(const std::vector<std::string>& inputs, const BuildOptions& options = {},
                            const LibraryProgress& progress = {});

// gather_library's models; a library without models is an error naming the inputs
// ("lib.fslib: the library has no models").
Library load_or_build_library(const std::vector<std::string>& inputs, const BuildOptions& options = {},
                              const LibraryProgress& progress = {});

}  // namespace fs::host
