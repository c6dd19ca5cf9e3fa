#include "host/web/assets.hpp"

#include <cstdlib>
#include <fstream>
#include <sstream>

#include "common/error.hpp"

namespace fs::host::web {

namespace stdfs = std::filesystem;

namespace {

stdfs::path self_dir() {
  std::error_code ec;
  const stdfs::path exe = stdfs::read_symlink("/proc/self/exe", ec);
  return ec ? stdfs::path() : exe.parent_path();
}

std::vector<stdfs::path> search_dirs(const std::string& name) {
  std::vector<stdfs::path> dirs;
  if (const char* env = std::getenv("FACETSCAN_WEB_DIR"); env && *env) dirs.emplace_back(env);
  if (const stdfs::path self = self_dir(); !self.empty())
    dirs.push_back(self / ".." / "share" / "facetscan" / "web");
  dirs.emplace_back("/usr/share/facetscan/web");
  dirs.emplace_back(FACETSCAN_WEB_SOURCE_DIR);
  if (name == "three.min.js") dirs.emplace_back(FACETSCAN_THREE_DIR);
  if (name == "OrbitControls.js") dirs.emplace_back(FACETSCAN_THREE_DIR "/examples/js/controls");
  return dirs;
}

}  // namespace

const std::vector<std::string>& asset_names() {
  static const std::vector<std::string> names = {"index.html", "app.js",       "view3d.js",
                                                 "style.css",  "three.min.js", "OrbitControls.js"};
  return names;
}

std::string mime_type(const stdfs::path& p) {
  const std::string e = p.extension().string();
  if (e == ".html") return "text/html; charset=utf-8";
  if (e == ".js") return "text/javascript; charset=utf-8";
  if (e == ".css") return "text/css; charset=utf-8";
  if (e == ".json") return "application/json";
  if (e == ".svg") return "image/svg+xml";
  if (e == ".png") return "image/png";
  return "application/octet-stream";
}

stdfs::path find_asset(const std::string& name) {
  std::string looked;
  for (const stdfs::path& d : search_dirs(name)) {
    const stdfs::path p = d / name;
    if (stdfs::is_regular_file(p)) return p;
    looked += " " + d.string();
  }
  throw Error("web asset " + name + " not found (looked in" + looked +
              "; install libjs-three or set FACETSCAN_WEB_DIR)");
}

std::map<std::string, Asset> load_assets() {
  std::map<std::string, Asset> out;
  for (const std::string& name : asset_names()) {
    const stdfs::path p = find_asset(name);
    std::ifstream f(p, std::ios::binary);
    std::ostringstream s;
    s << f.rdbuf();
    if (!f) throw Error(p.string() + ": cannot read");
    out[name] = {s.str(), mime_type(p)};
  }
  return out;
}

void copy_view_scripts(const stdfs::path& dir) {
  stdfs::create_directories(dir);
  for (const char* name : {"three.min.js", "OrbitControls.js", "view3d.js"})
    stdfs::copy_file(find_asset(name), dir / name, stdfs::copy_options::overwrite_existing);
}

}  // namespace fs::host::web
