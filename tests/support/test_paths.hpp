#pragma once
// Paths for tests: the source tree, the public data set (../shared/data) and the built binaries.
#include <filesystem>

namespace fs::test {

inline std::filesystem::path source_dir() { return FACETSCAN_SOURCE_DIR; }
inline std::filesystem::path shared_data() { return FACETSCAN_SHARED_DATA; }
inline std::filesystem::path bin_dir() { return FACETSCAN_BIN_DIR; }

}  // namespace fs::test
