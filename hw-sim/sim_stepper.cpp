#include "hw-sim/sim_stepper.hpp"

#include <cmath>
#include <limits>

namespace fs::sim {

SimStepperLines::SimStepperLines(SimMirror& mirror, FaultScript* faults, StepperTwinParams params)
    : mirror_(mirror), faults_(faults), p_(params), position_(params.start_position) {
  log_.reserve(p_.edge_log_capacity);
  mirror_.command(std::numeric_limits<fw::Nanos>::min() / 4, static_cast<double>(position_));
  home_closed_ = position_ <= p_.home_position;
}

void SimStepperLines::set_step(bool level, fw::Nanos now) {
  const bool rising = level && !step_;
  step_ = level;
  if (!rising || !enable_) return;
  const std::int64_t target = position_ + (dir_ ? 1 : -1);
  bool lost = false;
  if (now - last_step_ < p_.min_step_interval) {
    ++rate_violations_;
    lost = true;
  }
  if (!lost && faults_) {
    // Step triggers fire on the way up (the scan direction), not while homing passes by.
    const std::int64_t trig = dir_ ? target : std::numeric_limits<std::int64_t>::min();
    if (faults_->galvo_stalled(now, trig))
      lost = true;
    else if (faults_->galvo_pulse_lost(now, trig))
      lost = true;
  }
  if (log_.size() < p_.edge_log_capacity)
    log_.push_back(StepEdge{now, static_cast<std::int8_t>(lost ? 0 : (dir_ ? 1 : -1))});
  else
    log_overflow_ = true;
  if (lost) {
    ++lost_steps_;
    return;
  }
  last_step_ = now;
  position_ = target;
  ++accepted_;
  mirror_.command(now, static_cast<double>(position_));
  update_home(now);
}

void SimStepperLines::set_dir(bool level, fw::Nanos) { dir_ = level; }

void SimStepperLines::set_enable(bool level, fw::Nanos now) {
  enable_ = level;
  // A disabled motor holds no torque; the mirror stays where it is (no spring return modelled).
  if (!level) mirror_.freeze(now);
}

void SimStepperLines::update_home(fw::Nanos now) {
  const bool closed = position_ <= p_.home_position;
  if (closed == home_closed_) return;
  home_closed_ = closed;
  bool stuck_level = false;
  if (faults_ && faults_->home_stuck(now, position_, stuck_level)) return;  // a stuck switch makes no edges
  if (edge_count_ == edges_.size()) {                                       // overwrite the oldest event
    edge_head_ = (edge_head_ + 1) % edges_.size();
    --edge_count_;
  }
  edges_[(edge_head_ + edge_count_) % edges_.size()] = fw::GpioEdge{now, closed};
  ++edge_count_;
}

bool SimStepperLines::read_home(fw::Nanos now) {
  bool level = false;
  if (faults_ && faults_->home_stuck(now, position_, level)) return level;
  return home_closed_;
}

bool SimStepperLines::next_home_edge(fw::GpioEdge& edge) {
  if (edge_count_ == 0) return false;
  edge = edges_[edge_head_];
  edge_head_ = (edge_head_ + 1) % edges_.size();
  --edge_count_;
  return true;
}

bool SimStepperLines::read_position(double& steps, fw::Nanos now) {
  if (!p_.position_sensor) return false;
  steps = std::round(mirror_.position_at(now) * 64.0) / 64.0;
  return true;
}

void SimStepperLines::safe() noexcept {
  enable_ = false;
  step_ = false;
}

}  // namespace fs::sim
