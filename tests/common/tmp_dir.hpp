#pragma once
// A fresh temporary directory per test.
#include <unistd.h>
#include <atomic>
#include <filesystem>
#include <string>

namespace fs::test {

inline std::filesystem::path make_tmp_dir(const std::string& tag) {
  static std::atomic<int> counter{0};
  const auto p = std::filesystem::temp_directory_path() /
                 ("facetscan-" + tag + "-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p;
}

}  // namespace fs::test
