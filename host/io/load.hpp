#pragma once
// One entry point for every input the host accepts, yielding an organized cloud in millimetres:
//   .pcd   organized PCD (ascii / binary / binary_compressed)
//   .ply   PLY point cloud (organized if the header gives the grid)
//   .fscan native scan file, triangulated with the calibration in its ScanBegin header
// Units: PCD/PLY coordinates are multiplied by a scale (mm per file unit). Units::Auto treats a cloud whose
// largest |coordinate| is below kAutoMetresBelow as metres (Kinect/PCL clouds, e.g. mOSD) and scales by 1000;
// otherwise the file is taken to be in millimetres. An explicit scale > 0 overrides units.
#include <cstdint>
#include <string>

#include "host/io/cloud_readers.hpp"
#include "host/io/organized_cloud.hpp"
#include "host/io/triangulate.hpp"

namespace fs::host {

enum class Units { Auto, Millimetres, Metres };

struct LoadOptions {
  Units units = Units::Auto;
  double scale = 0.0;       // > 0: mm per file unit, overrides units
  bool load_labels = true;  // dataset labels ("label" field) into OrganizedCloud::labels
  std::uint64_t max_points = std::uint64_t(1) << 26;
  TriangulationOptions triangulation;  // .fscan input (its limits are replaced by `limits`)
  // .fscan input: the memory budget of the scan (ScanLimits::for_budget; `--memory-budget`). A ScanBegin
  // whose scan does not fit is refused ("<file>: at byte N: ScanBegin of scan ..."), before allocating.
  ScanLimits limits;
  static constexpr double kAutoMetresBelow = 20.0;
};

struct LoadInfo {
  std::string format;  // "pcd", "ply" or "fscan"
  double scale = 1.0;  // applied: mm per file unit
  std::size_t valid_points = 0;
  bool complete_scan = true;              // .fscan: false for a partial (aborted / disconnected) scan
  std::string scan_status;                // .fscan: to_string(ScanStatus)
  TriangulationStats triangulation;       // .fscan (shared_cell: stripe points that shared a cell, not kept)
  std::uint64_t stripe_points = 0;        // .fscan: stripe points stored
  std::uint32_t stripes_over_budget = 0;  // .fscan: stripes rejected for the memory budget
};

// Throws fs::Error naming the file (and byte offset) for unreadable or malformed input.
LoadInfo load_cloud(const std::string& path, OrganizedCloud& out, const LoadOptions& options = {});
// The .fscan part of load_cloud: triangulates a scan already read (from a file or an image named `name`) with
// its ScanBegin's calibration.
LoadInfo triangulate_loaded_scan(const Scan& scan, const std::string& name, const LoadOptions& options,
                                 OrganizedCloud& out);

// The segmentation profile (seg::SegmentParams::by_name) that suits a loaded input: "laser" for scans and for
// clouds in millimetres (e.g. a scan exported to PLY/PCD by `facetscan export`), "kinect" for clouds in
// metres (Kinect / PCL files such as the mOSD scans). `facetscan graph --preset auto` applies this rule; a
// PLY export of a laser scan segmented with the kinect profile loses recognition confidence.
const char* segment_profile_for(const LoadInfo& info);

// The scale load_cloud would apply to an already-read cloud (exposed for tests and the CLI).
double choose_scale(const OrganizedCloud& cloud, const LoadOptions& options);
// Multiplies points and viewpoint by scale.
void scale_cloud(OrganizedCloud& cloud, double scale);

}  // namespace fs::host
