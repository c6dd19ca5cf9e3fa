#pragma once
// The galvo mirror's mechanics: position (in galvo steps, fractional) versus time. Whatever drives it (the
// stepper twin from step pulses, the CiA 402 twin from its trajectory) calls command(t, target) and the
// mirror moves there as a critically damped second-order system with time constant tau (it settles to
// within 0.01 step after ~9 tau). freeze(t) models a stall: it stays where it is.
//
// position_at(t) answers for any t inside the recorded history (a fixed ring of the last kHistory commands),
// so the camera twin can ask where the mirror was at a frame's exposure time. No allocation.
#include <array>
#include <cstddef>
#include <cstdint>

#include "firmware/device/clock.hpp"

namespace fs::sim {

class SimMirror {
 public:
  static constexpr std::size_t kHistory = 512;

  explicit SimMirror(double start_position = 0.0, fw::Nanos tau_ns = 100'000);
  void command(fw::Nanos t, double target);
  void freeze(fw::Nanos t) { command(t, position_at(t)); }
  // Position at time t (clamped to the oldest remembered segment).
  double position_at(fw::Nanos t) const;
  double velocity_at(fw::Nanos t) const;  // steps per second
  // The last commanded target.
  double target() const { return seg_[head_].target; }
  fw::Nanos last_command_time() const { return seg_[head_].t0; }
  // Whether |position - target| <= tol from time t on (monotone once true, as the response does not
  // overshoot).
  bool settled_at(fw::Nanos t, double tol) const;
  // Time after which the response from the last command stays within tol of its target.
  fw::Nanos settle_time(double tol) const;
  fw::Nanos tau() const { return tau_; }
  void set_tau(fw::Nanos tau) { tau_ = tau > 0 ? tau : 1; }

 private:
  // From t0 on: x(t) = target + (a + b s) exp(-s), s = (t - t0) / tau.
  struct Segment {
    fw::Nanos t0 = 0;
    double target = 0.0, a = 0.0, b = 0.0;
  };
  const Segment& segment_for(fw::Nanos t) const;
  double eval(const Segment& s, fw::Nanos t) const;
  double eval_velocity(const Segment& s, fw::Nanos t) const;

  std::array<Segment, kHistory> seg_{};
  std::size_t head_ = 0, count_ = 1;
  fw::Nanos tau_;
};

}  // namespace fs::sim
