#pragma once
// The JSON shapes and the point format of the web API (docs/web-api.md), built once per scan in the
// recognizer's thread and then only read:
//   scan_detail_json(): /api/scans/ID: the recognition JSON (recognition_json.cpp) + the scan, each object's
//     colour and its model's faces (model frame: loops of 3D vertices), the table plane, the bounds, links;
//   points_blob(): /api/scans/ID/points: the scan's points, downsampled on the grid to <= max_points;
//   status_json(): /api/status and the "status" event.
#include <cstdint>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "common/calibration.hpp"
#include "common/messages.hpp"
#include "host/io/organized_cloud.hpp"
#include "host/recognize/recognizer.hpp"
#include "host/web/scan_history.hpp"

namespace fs::host::web {

// The scanner side, as the stream server sees it (updated by the serve / demo loop).
struct LiveStatus {
  std::string mode = "serve";  // serve | demo
  bool connected = false;      // a scanner is connected
  bool scanning = false;       // a scan is in progress
  bool recognizing = false;    // a scan is being recognized
  std::uint64_t scan_id = 0;   // the scan in progress (or the last one)
  std::uint32_t stripes = 0;   // stripes received of that scan
  std::uint32_t steps = 0;     // its step count
  double stripes_per_s = 0.0;  // over the last second
  std::uint64_t faults = 0;    // fault messages since start
  std::uint32_t last_fault_code = 0;
  std::uint64_t connections = 0, disconnects = 0, protocol_errors = 0, frames = 0;
  std::uint64_t scans = 0;  // scans recognized
  bool has_loop = false;    // the firmware's loop statistics of the last completed scan
  msg::LoopStats loop;
};
nlohmann::json status_json(const LiveStatus& s);

// Scan information for the detail and summary.
struct ScanInfo {
  std::uint64_t id = 0;       // the API's ID
  std::uint64_t scan_id = 0;  // the scanner's
  std::string title;
  std::string status = "complete";
  bool partial = false;
  std::uint32_t stripes = 0, steps = 0;
  std::int64_t result_unix_ms = 0;
  bool has_report = false, has_result = false, has_recording = false;
};

// Colour of object o (0-based) as "#rrggbb" (the report's and the PLY's palette).
std::string object_colour(std::size_t o);

// The full scene of one recognition. `table` may be null (unknown). `links_base` prefixes the report links
// ("/scans/ID/files/" live, "" in a report folder).
nlohmann::json scan_detail_json(const ScanInfo& info, const rec::Recognition& r, const Library& library,
                                const OrganizedCloud& cloud, const Plane* table);
// One row of /api/scans.
nlohmann::json scan_summary_json(const ScanInfo& info, const rec::Recognition& r, const Library& library);

// Points format (little-endian), version 1:
//   0  "FSPT"   4 u32 version (1)   8 u32 n   12 u32 flags (bit 0: region ids present)
//   16 f32 min x,y,z   28 f32 max x,y,z
//   40 f32 xyz[3n]   then u8 object[n] (255 = none)   then, only with flags bit 0: padding to even and
//   u16 region[n] (0xffff = none)
inline constexpr std::size_t kPointsHeader = 40;
inline constexpr std::size_t kDefaultMaxPoints = 80000;
std::string points_blob(const OrganizedCloud& cloud, const std::vector<std::int32_t>& object_labels,
                        const std::vector<std::int32_t>& region_labels,
                        std::size_t max_points = kDefaultMaxPoints);

// Builds the immutable record of a scan (detail, summary, points) from the recognizer's last result.
std::shared_ptr<ScanRecord> make_record(const ScanInfo& info, const OrganizedCloud& cloud,
                                        const rec::Recognizer& recognizer, const rec::Recognition& r,
                                        const Plane* table);

// The same scan's record with new info (e.g. the report's links once it is written): the JSON texts anew,
// the points, folder and recording taken over from `base` instead of computed again.
std::shared_ptr<ScanRecord> make_record(const ScanInfo& info, const ScanRecord& base,
                                        const OrganizedCloud& cloud, const rec::Recognizer& recognizer,
                                        const rec::Recognition& r, const Plane* table);

}  // namespace fs::host::web
