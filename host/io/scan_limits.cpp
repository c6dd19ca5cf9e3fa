// ScanLimits: the memory budget of one scan's processing (model in scan.hpp, numbers in
// docs/host-pipeline.md#memory-budget), and release_scan_memory.
#include "host/io/scan_limits.hpp"

#include <malloc.h>

#include <algorithm>
#include <thread>

#include "common/byte_size.hpp"
#include "common/error.hpp"

namespace fs::host {

namespace {

std::string budget_text(const ScanLimits& l) {
  return "the memory budget of " + format_byte_size(l.budget_bytes) + " (--memory-budget)";
}

std::string need_text(std::uint64_t bytes) { return "~" + format_byte_size(bytes); }

}  // namespace

std::uint32_t ScanLimits::resolve_threads(int threads) {
  if (threads > 0) return static_cast<std::uint32_t>(clamp_threads(static_cast<std::uint32_t>(threads)));
  return static_cast<std::uint32_t>(clamp_threads(std::thread::hardware_concurrency()));
}

ScanLimits ScanLimits::for_budget(std::uint64_t budget, int threads, int segment_row_step) {
  if (budget == 0) budget = kDefaultBudgetBytes;
  const std::uint32_t t = resolve_threads(threads);
  if (budget <= fixed_bytes(t))
    throw Error("memory budget " + format_byte_size(budget) +
                " is not above the fixed part of a scan's processing (" + format_byte_size(fixed_bytes(t)) +
                " with " + std::to_string(t) + " recognizer thread(s))");
  ScanLimits l;
  l.budget_bytes = budget;
  l.threads = t;
  l.segment_row_step = segment_row_step > 1 ? 2 : 1;
  l.max_steps = kMaxSteps;
  l.max_camera_side = kMaxCameraSide;
  l.max_cells = cells_for(budget, t, l.segment_row_step);
  l.max_ray_table_entries = available(budget, t) / kRayBytes;
  l.max_total_points = available(budget, t) / kPointBytes;
  return l;
}

namespace {

// What is wrong with the calibration's camera, steps or grid for `l` ("" = nothing; no allocation then).
std::string camera_problem(const ScanLimits& l, const ScannerCalibration& c) {
  const auto& cam = c.camera;
  if (cam.width == 0 || cam.width > l.max_camera_side || cam.height == 0 || cam.height > l.max_camera_side)
    return "camera " + std::to_string(cam.width) + " x " + std::to_string(cam.height) + " outside 1.." +
           std::to_string(l.max_camera_side) + " pixels per side";
  if (c.step_count == 0 || c.step_count > l.max_steps)
    return "step_count " + std::to_string(c.step_count) + " outside 1.." + std::to_string(l.max_steps) +
           (l.max_steps < ScanLimits::kMaxSteps ? " (" + budget_text(l) + ")" : std::string());
  const std::uint64_t rays = std::uint64_t(cam.height) * (std::uint64_t(cam.width) + 1);
  if (rays > l.max_ray_table_entries)
    return "camera " + std::to_string(cam.width) + " x " + std::to_string(cam.height) +
           " needs a ray table of " + need_text(rays * ScanLimits::kRayBytes) + ", above " + budget_text(l);
  const std::uint64_t cells = std::uint64_t(c.step_count) * cam.height;
  if (cells > l.max_cells)
    return "step_count " + std::to_string(c.step_count) + " x camera height " + std::to_string(cam.height) +
           " (" + std::to_string(cells) + " cells) need " +
           need_text(l.bytes(c.step_count, cam.height, cam.width, cells)) + ", above " + budget_text(l);
  return {};
}

}  // namespace

void ScanLimits::check_camera(const ScannerCalibration& c, const std::string& what) const {
  const std::string problem = camera_problem(*this, c);
  if (!problem.empty()) throw Error(what + ": " + problem);
}

void ScanLimits::check(const msg::ScanBegin& begin) const {
  const auto& c = begin.calibration;
  std::string problem = camera_problem(*this, c);
  // The whole scan with one stripe point per cell (the normal scan) must fit.
  const std::uint64_t cells = std::uint64_t(c.step_count) * c.camera.height;
  const std::uint64_t need = bytes(c.step_count, c.camera.height, c.camera.width, cells);
  if (problem.empty() && need > budget_bytes)
    problem = "step_count " + std::to_string(c.step_count) + " x camera height " +
              std::to_string(c.camera.height) + " (" + std::to_string(cells) + " cells, camera " +
              std::to_string(c.camera.width) + " x " + std::to_string(c.camera.height) + ") need " +
              need_text(need) + ", above " + budget_text(*this);
  if (!problem.empty()) throw Error("ScanBegin of scan " + std::to_string(begin.scan_id) + ": " + problem);
}

std::uint64_t ScanLimits::point_capacity(const ScannerCalibration& c) const {
  const std::uint64_t fixed = bytes(c.step_count, c.camera.height, c.camera.width, 0);
  const std::uint64_t left = budget_bytes > fixed ? (budget_bytes - fixed) / kPointBytes : 0;
  return std::min({left, max_total_points, std::uint64_t(c.step_count) * msg::kMaxStripePoints});
}

std::uint64_t release_scan_memory(Scan& scan, Triangulator& triangulator, OrganizedCloud* cloud,
                                  const WorkingSize& keep) {
  const std::uint64_t cells = std::uint64_t(keep.steps) * keep.rows;
  const std::uint64_t before = scan.storage_bytes() + triangulator.table_bytes() +
                               (cloud ? cloud->points.capacity() * sizeof(Eigen::Vector3f) : 0);
  if (scan.storage_bytes() > ScanLimits::scan_storage_bytes(keep.steps, cells))
    scan.release_storage(keep.steps, cells);
  if (triangulator.table_bytes() > ScanLimits::triangulator_bytes(keep.steps, keep.rows, keep.cols))
    triangulator.release();
  if (cloud && cloud->points.capacity() > cells) {
    cloud->points = std::vector<Eigen::Vector3f>();
    cloud->labels = std::vector<std::int32_t>();
    cloud->width = cloud->height = 0;
  }
  const std::uint64_t after = scan.storage_bytes() + triangulator.table_bytes() +
                              (cloud ? cloud->points.capacity() * sizeof(Eigen::Vector3f) : 0);
  if (after >= before) return 0;
  malloc_trim(0);
  return before - after;
}

}  // namespace fs::host
