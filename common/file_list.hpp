#pragma once
// Files named on a command line: plain files as given, directories expanded to their files (sorted) that
// `accept` takes. `kinds` names what is accepted in the error for a directory without any ("meshes").
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace fs {

// Throws fs::Error for a missing path or a directory with no accepted file.
std::vector<std::filesystem::path> collect_files(
    const std::vector<std::string>& inputs, const std::function<bool(const std::filesystem::path&)>& accept,
    const std::string& kinds);

}  // namespace fs
