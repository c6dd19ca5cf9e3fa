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
    case ScanStatus::OverBudget:
      return "stripe points above the memory budget";
  }
  return "?";
}

void Scan::reserve(std::uint32_t steps, std::uint64_t points) {
  if (slots_.size() < steps) slots_.resize(steps);
  if (points_.capacity() < points) points_.reserve(points);
  begin_.scanner_model.reserve(msg::kMaxModelName);
  begin_.units.reserve(16);
}

void Scan::start(const msg::ScanBegin& begin, const ScanLimits& limits) {
  const auto& cal = begin.calibration;
  limits.check(begin);  // throws before anything is allocated or changed
  // One point per image row per step is the normal case (within the capacity: check() made sure); more
  // points grow the buffer in add_stripe, up to the scan's point capacity.
  point_capacity_ = limits.point_capacity(cal);
  reserve(cal.step_count,
          std::min<std::uint64_t>(std::uint64_t(cal.step_count) * cal.camera.height, point_capacity_));
  begin_.scan_id = begin.scan_id;
  begin_.scanner_model = begin.scanner_model;
  begin_.calibration = begin.calibration;
  begin_.pixel_bits = begin.pixel_bits;
  begin_.units = begin.units;
  begin_.start_time_ns = begin.start_time_ns;
  std::fill(slots_.begin(), slots_.begin() + cal.step_count, Slot{});
  end_ = msg::ScanEnd{};
  points_.clear();
  used_ = 0;
  received_ = rejected_ = duplicates_ = over_budget_ = faults_ = last_fault_code_ = 0;
  status_ = ScanStatus::InProgress;
  started_ = true;
  has_end_ = false;
}

bool Scan::add_stripe(const msg::Stripe& stripe) {
  const auto& h = stripe.header;
  const std::int64_t slot = std::int64_t(h.step_index) - begin_.calibration.first_step;
  if (!started_ || status_ != ScanStatus::InProgress || h.scan_id != begin_.scan_id || slot < 0 ||
      slot >= std::int64_t(slot_count())) {
    ++rejected_;
    return false;
  }
  const std::uint64_t need = used_ + stripe.points.size();
  if (need > point_capacity_) {
    ++rejected_;
    ++over_budget_;
    return false;
  }
  if (need > points_.capacity())  // amortized growth, never beyond the scan's capacity
    points_.reserve(
        std::min<std::uint64_t>(std::max<std::uint64_t>(need, 2 * points_.capacity()), point_capacity_));
  Slot& s = slots_[static_cast<std::size_t>(slot)];
  if (s.present)
    ++duplicates_;  // a repeated step: the newer stripe wins
  else
    ++received_;
  s.header = h;
  s.first = used_;
  s.count = static_cast<std::uint32_t>(stripe.points.size());
  s.present = true;
  points_.insert(points_.end(), stripe.points.begin(), stripe.points.end());
  used_ = need;
  return true;
}

void Scan::finish(const msg::ScanEnd& end) {
  if (!started_ || status_ != ScanStatus::InProgress) return;
  end_ = end;
  has_end_ = true;
  if (!end.completed)
    status_ = ScanStatus::Aborted;
  else if (received_ < slot_count())
    status_ = over_budget_ > 0 ? ScanStatus::OverBudget : ScanStatus::MissingStripes;
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

static_assert(sizeof(msg::StripePoint) <= ScanLimits::kPointBytes, "the memory model's bytes per point");

void Scan::release_storage(std::uint32_t steps, std::uint64_t points) {
  static_assert(sizeof(Slot) <= ScanLimits::kSlotBytes, "the memory model's bytes per step");
  if (steps < slot_count() || points < used_) {
    // The scan does not fit the smaller storage: it is emptied (no stripes, no steps).
    begin_.calibration.step_count = 0;
    points_.clear();
    used_ = 0;
  }
  if (slots_.size() > steps) {
    slots_.resize(steps);
    slots_.shrink_to_fit();
  }
  if (points_.capacity() > points) {
    std::vector<msg::StripePoint> kept;
    kept.reserve(points);
    kept.assign(points_.begin(), points_.end());
    points_.swap(kept);
  }
}

std::uint64_t Scan::storage_bytes() const {
  return slots_.capacity() * sizeof(Slot) + points_.capacity() * sizeof(msg::StripePoint);
}

}  // namespace fs::host
