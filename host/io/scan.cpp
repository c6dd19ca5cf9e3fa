#include "host/io/scan.hpp"

#include <algorithm>

#include "common/error.hpp"

namespace fs::host {

const char* to_string(ScanStatus s) {
  switch (s) {
    case ScanStatus::InProgress:
      return "in progress";
    case ScanStatus::Complete:
      return "complete";
    case ScanStatus::Aborted:
      return "aborted by the scanner";
    case ScanStatus::MissingStripes:
      return "missing stripes";
    case ScanStatus::Disconnected:
      return "disconnected before ScanEnd";
    case ScanStatus::Superseded:
      return "superseded by a new scan";
    case ScanStatus::ProtocolError:
      return "connection closed for a protocol error";
  }
  return "?";
}

void Scan::reserve(std::uint32_t steps, std::uint64_t points) {
  if (slots_.size() < steps) slots_.resize(steps);
  if (points_.size() < points) points_.resize(points);
  begin_.scanner_model.reserve(msg::kMaxModelName);
  begin_.units.reserve(16);
}

void Scan::start(const msg::ScanBegin& begin, const ScanLimits& limits) {
  const auto& cal = begin.calibration;
  if (cal.step_count == 0 || cal.step_count > limits.max_steps)
    throw Error("ScanBegin of scan " + std::to_string(begin.scan_id) + ": step_count " +
                std::to_string(cal.step_count) + " outside 1.." + std::to_string(limits.max_steps));
  if (cal.camera.height == 0 || cal.camera.height > msg::kMaxStripePoints * 2u)
    throw Error("ScanBegin of scan " + std::to_string(begin.scan_id) + ": camera height " +
                std::to_string(cal.camera.height) + " out of range");
  // One point per image row per step is the normal case; storage beyond that comes from reserve().
  const std::uint64_t want =
      std::min<std::uint64_t>(std::uint64_t(cal.step_count) * cal.camera.height, limits.max_total_points);
  reserve(cal.step_count, want);
  begin_.scan_id = begin.scan_id;
  begin_.scanner_model = begin.scanner_model;
  begin_.calibration = begin.calibration;
  begin_.pixel_bits = begin.pixel_bits;
  begin_.units = begin.units;
  begin_.start_time_ns = begin.start_time_ns;
  std::fill(slots_.begin(), slots_.begin() + cal.step_count, Slot{});
  end_ = msg::ScanEnd{};
  used_ = 0;
  received_ = rejected_ = duplicates_ = faults_ = last_fault_code_ = 0;
  status_ = ScanStatus::InProgress;
  started_ = true;
  has_end_ = false;
}

bool Scan::add_stripe(const msg::Stripe& stripe) {
  const auto& h = stripe.header;
  const std::int64_t slot = std::int64_t(h.step_index) - begin_.calibration.first_step;
  if (!started_ || status_ != ScanStatus::InProgress || h.scan_id != begin_.scan_id || slot < 0 ||
      slot >= std::int64_t(slot_count()) || used_ + stripe.points.size() > points_.size()) {
    ++rejected_;
    return false;
  }
  Slot& s = slots_[static_cast<std::size_t>(slot)];
  if (s.present)
    ++duplicates_;  // a repeated step: the newer stripe wins
  else
    ++received_;
  s.header = h;
  s.first = used_;
  s.count = static_cast<std::uint32_t>(stripe.points.size());
  s.present = true;
  std::copy(stripe.points.begin(), stripe.points.end(), points_.begin() + static_cast<std::ptrdiff_t>(used_));
  used_ += stripe.points.size();
  return true;
}

void Scan::finish(const msg::ScanEnd& end) {
  if (!started_ || status_ != ScanStatus::InProgress) return;
  end_ = end;
  has_end_ = true;
  if (!end.completed)
    status_ = ScanStatus::Aborted;
  else if (received_ < slot_count())
    status_ = ScanStatus::MissingStripes;
  else
    status_ = ScanStatus::Complete;
}

void Scan::interrupt(ScanStatus why) {
  if (started_ && status_ == ScanStatus::InProgress) status_ = why;
}

void Scan::note_fault(const msg::Fault& fault) {
  ++faults_;
  last_fault_code_ = fault.code;
}

}  // namespace fs::host
