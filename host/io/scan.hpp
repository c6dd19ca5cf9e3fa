#pragma once
// A native scan: the ScanBegin header (with the calibration), the stripes indexed by galvo step (column
// k - first_step) and the ScanEnd. A scan is complete when its ScanEnd says completed and every step's
// stripe arrived; otherwise it is partial and says why.
//
// Memory: one slot per step, and the stripe points in one buffer that start() reserves for one point per
// image row per step (the normal scan) and that grows on demand (amortized) up to the scan's point capacity,
// the budget left by its other parts (ScanLimits). A warm Scan (reserve(), or a previous scan of the same
// size) allocates nothing. A stripe that would exceed the capacity is rejected and counted
// (stripes_over_budget()); such a scan ends as OverBudget, not MissingStripes.
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "common/messages.hpp"

namespace fs::host {

enum class ScanStatus : std::uint8_t {
  InProgress,      // no ScanEnd yet
  Complete,        // ScanEnd(completed) and all steps present
  Aborted,         // ScanEnd says the firmware aborted
  MissingStripes,  // ScanEnd(completed) but some steps never arrived (dropped frames / stripes)
  Disconnected,    // the stream / file ended before ScanEnd
  Superseded,      // a new ScanBegin arrived before ScanEnd
  ProtocolError,   // the connection was closed for a malformed frame and the scan was not resumed
  OverBudget,      // ScanEnd(completed) but stripes were rejected: their points exceed the memory budget
};
const char* to_string(ScanStatus s);

// What one scan's processing may use, derived from a memory budget (`--memory-budget`, default 2 GiB) and
// the recognizer's thread count. The model (bytes; docs/host-pipeline.md#memory-budget, measured with
// bench_scan_memory) for a scan of S steps, a camera of H rows x W columns, P stored stripe points and
// C = S x H grid cells, with T recognizer threads:
//   Scan storage      S x kSlotBytes + P x kPointBytes
//   Triangulator      H x (W + 1) x kRayBytes (ray table) + S x kPlaneBytes + H x kRowScratchBytes + scratch
//   OrganizedCloud    C x kCloudBytesPerCell
//   Recognizer        C x (kRecognizerBytesPerCell + (T - 1) x kRecognizerBytesPerCellPerThread)
//                     (+ C x kRowThinningBytesPerCell with RecognizeParams::segment_row_step 2)
//   fixed             kFixedBytes + (T - 1) x kFixedBytesPerThread (recognizer tables and workers)
// The recognizer's terms are what it reserves (an upper bound: a real scan touches about a third; test
// RecognizerMemory.* keeps them above what it requests).
// A ScanBegin is refused (before anything is allocated) when its scan with one point per cell does not fit;
// the stripe points it may store are what is left of the budget (point_capacity). The library and the
// program itself are outside the budget.
struct ScanLimits {
  static constexpr std::uint64_t kDefaultBudgetBytes = std::uint64_t(2) << 30;  // 2 GiB
  static constexpr std::uint32_t kMaxSteps = 65536;       // hard cap, whatever the budget
  static constexpr std::uint32_t kMaxCameraSide = 16384;  // hard cap on camera width and height
  static constexpr std::uint32_t kMaxThreads = 1024;      // thread counts above are taken as this
  static constexpr std::uint64_t kSlotBytes = 64;         // per step: Scan slot (stripe header + index)
  static constexpr std::uint64_t kPointBytes = 16;        // per stored stripe point (msg::StripePoint)
  static constexpr std::uint64_t kRayBytes = 12;          // per ray-table entry (3 floats)
  static constexpr std::uint64_t kPlaneBytes = 16;        // per step: the laser plane
  static constexpr std::uint64_t kRowScratchBytes = 6;    // per camera row: triangulation scratch
  static constexpr std::uint64_t kStripeScratchBytes = 4 * msg::kMaxStripePoints;  // smoothing scratch
  static constexpr std::uint64_t kCloudBytesPerCell = 12;                          // Eigen::Vector3f per cell
  static constexpr std::uint64_t kRecognizerBytesPerCell = 412;          // measured: 410.5 (1 thread)
  static constexpr std::uint64_t kRecognizerBytesPerCellPerThread = 15;  // measured: 15 per extra thread
  // RecognizeParams::segment_row_step 2 adds the thinned cloud and its segmenter.
  static constexpr std::uint64_t kRowThinningBytesPerCell = 52;          // measured: 49.5
  static constexpr std::uint64_t kFixedBytes = std::uint64_t(32) << 20;  // measured: 29.1 MiB (1 thread)
  static constexpr std::uint64_t kFixedBytesPerThread = std::uint64_t(13) << 20;  // measured: 12.3 MiB

  // Model pieces (threads >= 1).
  static constexpr std::uint64_t scan_storage_bytes(std::uint64_t steps, std::uint64_t points) {
    return steps * kSlotBytes + points * kPointBytes;
  }
  static constexpr std::uint64_t triangulator_bytes(std::uint64_t steps, std::uint64_t rows,
                                                    std::uint64_t cols) {
    return rows * (cols + 1) * kRayBytes + steps * kPlaneBytes + rows * kRowScratchBytes +
           kStripeScratchBytes;
  }
  static constexpr std::uint64_t recognizer_bytes_per_cell(std::uint32_t threads,
                                                           std::uint32_t segment_row_step = 1) {
    return kRecognizerBytesPerCell + (clamp_threads(threads) - 1) * kRecognizerBytesPerCellPerThread +
           (segment_row_step > 1 ? kRowThinningBytesPerCell : 0);
  }
  static constexpr std::uint64_t recognizer_bytes(std::uint64_t cells, std::uint32_t threads = 1,
                                                  std::uint32_t segment_row_step = 1) {
    return cells * recognizer_bytes_per_cell(threads, segment_row_step);  // without the fixed part
  }
  static constexpr std::uint64_t fixed_bytes(std::uint32_t threads) {
    return kFixedBytes + (clamp_threads(threads) - 1) * kFixedBytesPerThread;
  }
  // The whole model: a scan of `steps` x camera `rows` x `cols` with `points` stored stripe points.
  static constexpr std::uint64_t scan_bytes(std::uint64_t steps, std::uint64_t rows, std::uint64_t cols,
                                            std::uint64_t points, std::uint32_t threads,
                                            std::uint32_t segment_row_step = 1) {
    return fixed_bytes(threads) + scan_storage_bytes(steps, points) + triangulator_bytes(steps, rows, cols) +
           steps * rows * (kCloudBytesPerCell + recognizer_bytes_per_cell(threads, segment_row_step));
  }
  static constexpr std::uint64_t clamp_threads(std::uint32_t threads) {
    return threads < 1 ? 1 : threads > kMaxThreads ? kMaxThreads : threads;
  }
  // The recognizer's thread count for RecognizeParams::threads (0 = hardware concurrency).
  static std::uint32_t resolve_threads(int threads);

  std::uint64_t budget_bytes = kDefaultBudgetBytes;  // the budget the limits below come from
  std::uint32_t threads = resolve_threads(0);        // recognizer threads the budget accounts for
  std::uint32_t segment_row_step = 1;                // the recognizer's RecognizeParams::segment_row_step
  // Per-field caps (each alone; the whole scan must also fit: check()).
  std::uint32_t max_steps = kMaxSteps;                         // ScanBegin.step_count
  std::uint32_t max_camera_side = kMaxCameraSide;              // camera width and height
  std::uint64_t max_cells = cells_for(budget_bytes, threads);  // step_count x camera height
  std::uint64_t max_ray_table_entries = available(budget_bytes, threads) / kRayBytes;  // height x (width + 1)
  std::uint64_t max_total_points = available(budget_bytes, threads) / kPointBytes;  // stripe points per scan

  // The limits of a budget in bytes (0 = the default) for a recognizer of `threads` threads (0 = hardware
  // concurrency, as RecognizeParams::threads). ScanLimits{} == for_budget(kDefaultBudgetBytes, 0). Throws
  // fs::Error when the budget is not above the fixed part.
  // segment_row_step: the recognizer's RecognizeParams::segment_row_step (2 adds kRowThinningBytesPerCell).
  static ScanLimits for_budget(std::uint64_t budget_bytes, int threads = 0, int segment_row_step = 1);
  // The model for these limits' thread count.
  std::uint64_t bytes(std::uint64_t steps, std::uint64_t rows, std::uint64_t cols,
                      std::uint64_t points) const {
    return scan_bytes(steps, rows, cols, points, threads, segment_row_step);
  }
  // Throws fs::Error naming the scan, the field, the memory needed and the budget when the ScanBegin's scan
  // (steps x camera, one stripe point per cell) does not fit. Allocates nothing unless it throws.
  void check(const msg::ScanBegin& begin) const;
  // Throws fs::Error ("calibration: camera W x H needs a ray table of ...") when the camera or the grid of
  // `calibration` exceeds the limits (what Triangulator::configure allocates). `what` prefixes the message.
  void check_camera(const ScannerCalibration& calibration, const std::string& what) const;
  // Stripe points a scan with this calibration may store: the budget left after its other parts, at most
  // max_total_points and step_count x msg::kMaxStripePoints (the wire's maximum).
  std::uint64_t point_capacity(const ScannerCalibration& calibration) const;

 private:
  static constexpr std::uint64_t available(std::uint64_t budget, std::uint32_t threads) {
    return budget > fixed_bytes(threads) ? budget - fixed_bytes(threads) : 0;
  }
  static constexpr std::uint64_t cells_for(std::uint64_t budget, std::uint32_t threads,
                                           std::uint32_t segment_row_step = 1) {
    // with one stripe point per cell
    return available(budget, threads) /
           (kCloudBytesPerCell + recognizer_bytes_per_cell(threads, segment_row_step) + kPointBytes);
  }
};

class Scan {
 public:
  // Reserves storage for scans of up to `steps` steps and `points` stripe points (warm-up).
  void reserve(std::uint32_t steps, std::uint64_t points);

  // Starts a scan: checks the ScanBegin against `limits` (ScanLimits::check: throws fs::Error naming the scan
  // and the field, before allocating anything; the Scan is then unchanged), then clears the stripes and
  // reserves one point per row per step (no allocation when within the reserved capacity).
  void start(const msg::ScanBegin& begin, const ScanLimits& limits = {});
  // Stores one stripe (its points are copied; the point buffer grows if needed). Returns false when it does
  // not belong to this scan (wrong scan_id, step outside the scan) or its points would exceed the scan's
  // point capacity (also counted in stripes_over_budget()); the stripe is counted as rejected.
  bool add_stripe(const msg::Stripe& stripe);
  void finish(const msg::ScanEnd& end);
  // Ends the scan without a ScanEnd (stream closed, new scan started).
  void interrupt(ScanStatus why);
  void note_fault(const msg::Fault& fault);
  // Frees storage beyond what a scan of `steps` steps and `points` stripe points needs. Call it after a
  // delivered scan once its data is no longer used, when storage_bytes() is above the usual working size
  // (e.g. ScanLimits::scan_storage_bytes of the normal scan), then malloc_trim(0) to return the pages to the
  // system (release_scan_memory in host/io/scan_limits.hpp does all of it). A scan that does not fit in
  // `steps` x `points` (slot_count() > steps or points_stored() > points) is emptied: no steps, no stripes.
  void release_storage(std::uint32_t steps, std::uint64_t points);
  // Heap bytes held (slot and point capacity).
  std::uint64_t storage_bytes() const;

  bool started() const { return started_; }
  ScanStatus status() const { return status_; }
  bool complete() const { return status_ == ScanStatus::Complete; }
  const msg::ScanBegin& begin_message() const { return begin_; }
  const msg::ScanEnd& end_message() const { return end_; }
  bool has_end() const { return has_end_; }
  std::uint64_t scan_id() const { return begin_.scan_id; }

  std::uint32_t slot_count() const { return begin_.calibration.step_count; }  // columns
  bool has_stripe(std::uint32_t slot) const { return slot < slot_count() && slots_[slot].present; }
  const msg::StripeHeader& stripe_header(std::uint32_t slot) const { return slots_[slot].header; }
  std::span<const msg::StripePoint> stripe_points(std::uint32_t slot) const {
    const Slot& s = slots_[slot];
    return {points_.data() + s.first, s.count};
  }
  std::uint32_t stripes_received() const { return received_; }
  std::uint32_t stripes_rejected() const { return rejected_; }
  std::uint32_t stripes_over_budget() const { return over_budget_; }  // rejected for the point capacity
  std::uint64_t point_capacity() const { return point_capacity_; }
  std::uint32_t duplicate_stripes() const { return duplicates_; }
  std::uint64_t points_stored() const { return used_; }
  std::uint32_t faults() const { return faults_; }
  std::uint32_t last_fault_code() const { return last_fault_code_; }

 private:
  struct Slot {
    msg::StripeHeader header;
    std::uint64_t first = 0;
    std::uint32_t count = 0;
    bool present = false;
  };
  msg::ScanBegin begin_;
  msg::ScanEnd end_;
  std::vector<Slot> slots_;
  std::vector<msg::StripePoint> points_;  // size() = used_ (the stored points); capacity grows on demand
  std::uint64_t used_ = 0;
  std::uint64_t point_capacity_ = 0;  // of this scan (ScanLimits::point_capacity)
  std::uint32_t received_ = 0, rejected_ = 0, duplicates_ = 0, over_budget_ = 0, faults_ = 0,
                last_fault_code_ = 0;
  ScanStatus status_ = ScanStatus::InProgress;
  bool started_ = false, has_end_ = false;
};

}  // namespace fs::host
