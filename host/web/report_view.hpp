#pragma once
// The HTML report with the live page's 3D view, self-contained: rec::write_report's page and pictures, plus
// js/three.min.js, js/OrbitControls.js, js/view3d.js (copied, assets.hpp) and scene-data.js (the scan's
// /api/scans/ID JSON and its points, base64) loaded as classic scripts, so that index.html opens from disk
// (file://) in any browser with no server and no network.
#include <filesystem>
#include <string>

#include "common/calibration.hpp"
#include "host/io/organized_cloud.hpp"
#include "host/recognize/recognizer.hpp"

namespace fs::host::web {

void write_report(const std::filesystem::path& dir, const std::string& title, const OrganizedCloud& cloud,
                  const rec::Recognizer& recognizer, const rec::Recognition& r, const Plane* table = nullptr);

}  // namespace fs::host::web
