#include "firmware/galvo/stepper_galvo.hpp"

#include <cmath>

namespace fs::fw {

StepperGalvo::StepperGalvo(GpioLines& lines, StepperGalvoParams params)
    : lines_(lines),
      p_(params),
      min_interval_(static_cast<Nanos>(std::ceil(1e9 / std::max(1.0, params.max_step_rate)))) {}

void StepperGalvo::enable(Nanos now) {
  lines_.set_enable(true, now);
  lines_.set_step(false, now);
  enabled_ = true;
}

void StepperGalvo::disable() noexcept {
  lines_.safe();
  enabled_ = false;
  phase_ = Phase::Idle;
}

void StepperGalvo::reset_fault(Nanos now) {
  fault_ = GalvoFault::None;
  homed_ = false;  // position is unknown after a fault
  phase_ = Phase::Idle;
  (void)now;
}

void StepperGalvo::start_homing(Nanos now) {
  if (!enabled_) enable(now);
  fault_ = GalvoFault::None;
  homed_ = false;
  phase_ = Phase::HomingSearch;
  search_steps_ = 0;
  fw::GpioEdge e;
  while (lines_.next_home_edge(e)) {
  }
}

void StepperGalvo::move_to(std::int32_t step, Nanos now) {
  target_ = step;
  if (step == position_ && phase_ == Phase::Idle) return;
  phase_ = Phase::Moving;
  move_start_pos_ = position_;
  has_sensor_ = lines_.read_position(move_start_measured_, now);
  checked_ = false;
}

void StepperGalvo::pulse(bool up, Nanos now) {
  if (up != dir_) {
    lines_.set_dir(up, now);
    dir_ = up;
  }
  lines_.set_step(true, now);
  lines_.set_step(false, now);
  last_pulse_ = now;
  position_ += up ? 1 : -1;
}

GalvoStatus StepperGalvo::poll(Nanos now) {
  const bool can_pulse = enabled_ && fault_ == GalvoFault::None && now - last_pulse_ >= min_interval_;
  switch (phase_) {
    case Phase::Idle:
      break;
    case Phase::Moving:
      if (position_ == target_) {
        phase_ = Phase::Idle;
      } else if (can_pulse) {
        pulse(target_ > position_, now);
      }
      break;
    case Phase::HomingSearch: {
      GpioEdge e;
      bool closed = false;
      while (lines_.next_home_edge(e)) closed = closed || e.rising;
      closed = closed || lines_.read_home(now);
      if (closed) {
        position_ = p_.home_position;
        target_ = p_.home_position + p_.home_backoff;
        phase_ = Phase::HomingBackoff;
      } else if (search_steps_ >= p_.home_range) {
        set_fault(GalvoFault::HomeNotFound);
        phase_ = Phase::Idle;
      } else if (can_pulse) {
        pulse(false, now);
        ++search_steps_;
      }
      break;
    }
    case Phase::HomingBackoff:
      if (position_ != target_) {
        if (can_pulse) pulse(true, now);
      } else if (now - last_pulse_ >= p_.settle_time) {
        GpioEdge e;
        while (lines_.next_home_edge(e)) {
        }
        if (lines_.read_home(now)) {
          set_fault(GalvoFault::HomeNotFound);  // the switch did not open: stuck closed
        } else {
          homed_ = true;
        }
        checked_ = true;
        phase_ = Phase::Idle;
      }
      break;
  }

  double m = static_cast<double>(position_);
  const bool sensor = lines_.read_position(m, now);
  measured_ = sensor ? m : static_cast<double>(position_);
  const bool settled = phase_ == Phase::Idle && now - last_pulse_ >= p_.settle_time;
  if (settled && !checked_ && fault_ == GalvoFault::None) {
    checked_ = true;
    if (sensor && has_sensor_) {
      const double err = std::abs(measured_ - static_cast<double>(position_));
      const double travelled = std::abs(measured_ - move_start_measured_);
      if (err > p_.position_tolerance) {
        const bool no_motion = travelled < 0.5 && std::abs(position_ - move_start_pos_) >= 1;
        set_fault(no_motion ? GalvoFault::Stall : GalvoFault::MissedSteps);
      }
    }
  }
  GalvoStatus s;
  s.commanded_step = position_;
  s.measured_step = measured_;
  s.moving = phase_ != Phase::Idle;
  s.in_position = settled && checked_ && fault_ == GalvoFault::None && position_ == target_;
  s.homed = homed_;
  s.enabled = enabled_;
  s.fault = fault_;
  return s;
}

}  // namespace fs::fw
