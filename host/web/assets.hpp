#pragma once
// The page, its scripts and three.js, found at run time (first match wins):
//   $FACETSCAN_WEB_DIR; <binary dir>/../share/facetscan/web (the build tree: build/share/facetscan/web, which
//   CMake fills; installed: /usr/share/facetscan/web); /usr/share/facetscan/web; the source tree's
//   host/web/assets with three.js from /usr/share/javascript/three (libjs-three).
// Only the fixed list of names below is ever served (no file-system path comes from a request).
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace fs::host::web {

struct Asset {
  std::string content;
  std::string mime;
};

// Every served asset name (index.html, app.js, view3d.js, style.css, three.min.js, OrbitControls.js).
const std::vector<std::string>& asset_names();
// Where each asset is (throws fs::Error naming what is missing and where it looked).
std::filesystem::path find_asset(const std::string& name);
// Loads every asset into memory.
std::map<std::string, Asset> load_assets();
// Copies the 3D view's scripts (three.min.js, OrbitControls.js, view3d.js) into dir (for a report).
void copy_view_scripts(const std::filesystem::path& dir);
// Content type by file extension (for the scan files).
std::string mime_type(const std::filesystem::path& p);

}  // namespace fs::host::web
