// Fuzz target: the web view's file paths (resolve_under, what /scans/ID/files/PATH serves). Whatever the
// request path, the result is either nothing or a regular file inside the scan's folder after resolving
// symlinks; a symlink leading out of the folder is never followed.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include "host/web/http_server.hpp"

namespace {

namespace stdfs = std::filesystem;

// root/{a.txt, sub/b.txt, out -> ../secret}, secret/s.txt beside root: built once per process.
struct Tree {
  stdfs::path top, root;
  Tree() {
    top = stdfs::temp_directory_path() / ("facetscan-fuzz-web-path-" + std::to_string(getpid()));
    root = top / "root";
    stdfs::create_directories(root / "sub");
    stdfs::create_directories(top / "secret");
    std::ofstream(root / "a.txt") << "a";
    std::ofstream(root / "sub" / "b.txt") << "b";
    std::ofstream(top / "secret" / "s.txt") << "s";
    std::error_code ec;
    stdfs::create_directory_symlink(top / "secret", root / "out", ec);
    root = stdfs::canonical(root);
  }
  ~Tree() {
    std::error_code ec;
    stdfs::remove_all(top, ec);
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const Tree tree;
  const std::string_view rel(reinterpret_cast<const char*>(data), size);
  const auto p = fs::host::web::resolve_under(tree.root, rel);
  if (!p) return 0;
  if (!stdfs::is_regular_file(*p)) __builtin_trap();
  // Inside root, component by component.
  auto r = tree.root.begin();
  auto q = p->begin();
  for (; r != tree.root.end(); ++r, ++q)
    if (q == p->end() || *r != *q) __builtin_trap();
  return 0;
}
