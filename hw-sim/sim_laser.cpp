#include "hw-sim/sim_laser.hpp"

#include <algorithm>

namespace fs::sim {

SimLaser::SimLaser(FaultScript* faults, std::size_t log_capacity) : faults_(faults), capacity_(log_capacity) {
  log_.reserve(capacity_);
}

void SimLaser::record(fw::Nanos t, bool forced) noexcept {
  if (log_.size() < capacity_)
    log_.push_back(LaserEvent{t, commanded_, emitting_, forced});
  else
    overflow_ = true;
}

void SimLaser::set(bool on, fw::Nanos now) {
  last_t_ = std::max(last_t_, now);
  if (on && !commanded_) ++switch_ons_;
  commanded_ = on;
  bool stuck = false;
  emitting_ = on;
  if (faults_ && faults_->laser_stuck(now, static_cast<std::int64_t>(switch_ons_) - 1, stuck))
    emitting_ = stuck;
  record(now, false);
}

void SimLaser::force_off() noexcept {
  commanded_ = false;
  bool stuck = false;
  emitting_ = false;
  if (faults_ && faults_->laser_stuck(last_t_, static_cast<std::int64_t>(switch_ons_) - 1, stuck))
    emitting_ = stuck;
  record(last_t_, true);
}

bool SimLaser::emitting_at(fw::Nanos t) const {
  // Last event at or before t.
  auto it =
      std::upper_bound(log_.begin(), log_.end(), t, [](fw::Nanos v, const LaserEvent& e) { return v < e.t; });
  if (it == log_.begin()) return false;
  return std::prev(it)->emitting;
}

double SimLaser::on_fraction(fw::Nanos t0, fw::Nanos t1) const {
  if (t1 <= t0) return emitting_at(t0) ? 1.0 : 0.0;
  auto it = std::upper_bound(log_.begin(), log_.end(), t0,
                             [](fw::Nanos v, const LaserEvent& e) { return v < e.t; });
  bool on = it == log_.begin() ? false : std::prev(it)->emitting;
  fw::Nanos t = t0, lit = 0;
  for (; it != log_.end() && it->t < t1; ++it) {
    if (on) lit += it->t - t;
    t = it->t;
    on = it->emitting;
  }
  if (on) lit += t1 - t;
  return static_cast<double>(lit) / static_cast<double>(t1 - t0);
}

}  // namespace fs::sim
