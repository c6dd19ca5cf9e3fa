#include "host/io/load.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "common/error.hpp"
#include "host/io/scan.hpp"
#include "host/io/scan_assembler.hpp"

namespace fs::host {

double choose_scale(const OrganizedCloud& cloud, const LoadOptions& options) {
  if (options.scale > 0.0) return options.scale;
  if (options.units == Units::Millimetres) return 1.0;
  if (options.units == Units::Metres) return 1000.0;
  float max_abs = 0.0f;
  for (const auto& p : cloud.points)
    if (OrganizedCloud::valid(p)) max_abs = std::max(max_abs, p.cwiseAbs().maxCoeff());
  if (max_abs == 0.0f) return 1.0;
  return max_abs < LoadOptions::kAutoMetresBelow ? 1000.0 : 1.0;
}

const char* segment_profile_for(const LoadInfo& info) {
  return info.format != "fscan" && info.scale >= 999.0 ? "kinect" : "laser";
}

void scale_cloud(OrganizedCloud& cloud, double scale) {
  if (scale == 1.0) return;
  const float s = static_cast<float>(scale);
  for (auto& p : cloud.points) p *= s;  // NaN stays NaN
  cloud.viewpoint *= scale;
}

namespace {
std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}
}  // namespace

LoadInfo load_cloud(const std::string& path, OrganizedCloud& out, const LoadOptions& options) {
  const std::string ext = lower_extension(path);
  LoadInfo info;
  CloudReadOptions ro;
  ro.max_points = options.max_points;
  ro.load_labels = options.load_labels;
  if (ext == ".pcd" || ext == ".ply") {
    const auto bytes = read_file_bytes(path);
    if (ext == ".pcd") {
      read_pcd(bytes.span(), path, out, ro);
      info.format = "pcd";
    } else {
      read_ply(bytes.span(), path, out, ro);
      info.format = "ply";
    }
    info.scale = choose_scale(out, options);
    scale_cloud(out, info.scale);
  } else if (ext == ".fscan") {
    Scan scan;
    load_scan(path, scan, options.limits);
    return triangulate_loaded_scan(scan, path, options, out);
  } else {
    throw Error(path + ": unknown point-cloud format '" + ext + "' (expected .pcd, .ply or .fscan)");
  }
  info.valid_points = out.valid_count();
  return info;
}

LoadInfo triangulate_loaded_scan(const Scan& scan, const std::string& name, const LoadOptions& options,
                                 OrganizedCloud& out) {
  LoadInfo info;
  TriangulationOptions to = options.triangulation;
  to.limits = options.limits;
  Triangulator tri;
  try {
    tri.configure(scan.begin_message().calibration, to);
  } catch (const Error& e) {
    throw Error(name + ": " + e.what());
  }
  info.triangulation = tri.triangulate(scan, out);
  info.format = "fscan";
  info.complete_scan = scan.complete();
  info.scan_status = to_string(scan.status());
  info.stripe_points = scan.points_stored();
  info.stripes_over_budget = scan.stripes_over_budget();
  info.valid_points = out.valid_count();
  return info;
}

}  // namespace fs::host
