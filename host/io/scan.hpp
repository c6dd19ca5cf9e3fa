#pragma once
// A native scan: the ScanBegin header (with the calibration), the stripes indexed by galvo step (column
// k - first_step) in storage reserved up front, and the ScanEnd. A scan is complete when its ScanEnd says
// completed and every step's stripe arrived; otherwise it is partial and says why.
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
};
const char* to_string(ScanStatus s);

struct ScanLimits {
  std::uint32_t max_steps = 65536;            // ScanBegin.step_count above this is refused
  std::uint64_t max_total_points = 1u << 24;  // stripe points stored per scan (16 M points, 192 MB)
};

class Scan {
 public:
  // Reserves storage for scans of up to `steps` steps and `points` stripe points (warm-up).
  void reserve(std::uint32_t steps, std::uint64_t points);

  // Starts a scan: clears the stripes (no allocation when within the reserved capacity).
  void start(const msg::ScanBegin& begin, const ScanLimits& limits = {});
  // Stores one stripe (its points are copied). Returns false when it does not belong to this scan (wrong
  // scan_id, step outside the scan, point storage exhausted); the stripe is counted as rejected.
  bool add_stripe(const msg::Stripe& stripe);
  void finish(const msg::ScanEnd& end);
  // Ends the scan without a ScanEnd (stream closed, new scan started).
  void interrupt(ScanStatus why);
  void note_fault(const msg::Fault& fault);

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
  std::vector<msg::StripePoint> points_;  // size() = capacity in use; used_ = filled
  std::uint64_t used_ = 0;
  std::uint32_t received_ = 0, rejected_ = 0, duplicates_ = 0, faults_ = 0, last_fault_code_ = 0;
  ScanStatus status_ = ScanStatus::InProgress;
  bool started_ = false, has_end_ = false;
};

}  // namespace fs::host
