#include "common/file_list.hpp"

#include <algorithm>

#include "common/error.hpp"

namespace fs {

std::vector<std::filesystem::path> collect_files(
    const std::vector<std::string>& inputs, const std::function<bool(const std::filesystem::path&)>& accept,
    const std::string& kinds) {
  namespace stdfs = std::filesystem;
  std::vector<stdfs::path> files;
  for (const auto& in : inputs) {
    const stdfs::path p(in);
    if (stdfs::is_directory(p)) {
      std::vector<stdfs::path> found;
      for (const auto& e : stdfs::directory_iterator(p))
        if (e.is_regular_file() && accept(e.path())) found.push_back(e.path());
      if (found.empty()) throw Error(in + ": no " + kinds + " in this directory");
      std::sort(found.begin(), found.end());
      files.insert(files.end(), found.begin(), found.end());
    } else if (stdfs::exists(p)) {
      files.push_back(p);
    } else {
      throw Error(in + ": no such file or directory");
    }
  }
  return files;
}

}  // namespace fs
