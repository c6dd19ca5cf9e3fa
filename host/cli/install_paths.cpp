#include "host/cli/install_paths.hpp"

#include "common/error.hpp"

namespace fs::host::cli {

namespace stdfs = std::filesystem;

stdfs::path self_dir() {
  std::error_code ec;
  const stdfs::path exe = stdfs::read_symlink("/proc/self/exe", ec);
  return ec ? stdfs::current_path() : exe.parent_path();
}

stdfs::path scenes_dir() {
  for (const stdfs::path& p : {stdfs::path(FACETSCAN_SCENES_DIR), stdfs::path("/usr/share/facetscan/scenes")})
    if (stdfs::is_directory(p)) return p;
  throw Error("cannot find the shipped scenes (looked in " FACETSCAN_SCENES_DIR
              " and /usr/share/facetscan/scenes)");
}

}  // namespace fs::host::cli
