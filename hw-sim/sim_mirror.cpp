#include "hw-sim/sim_mirror.hpp"

#include <cmath>
#include <limits>

namespace fs::sim {

SimMirror::SimMirror(double start_position, fw::Nanos tau_ns) : tau_(tau_ns > 0 ? tau_ns : 1) {
  seg_[0] = Segment{std::numeric_limits<fw::Nanos>::min() / 2, start_position, 0.0, 0.0};
}

double SimMirror::eval(const Segment& s, fw::Nanos t) const {
  if (t <= s.t0) return s.target + s.a;
  const double x = static_cast<double>(t - s.t0) / static_cast<double>(tau_);
  if (x > 60.0) return s.target;
  return s.target + (s.a + s.b * x) * std::exp(-x);
}

double SimMirror::eval_velocity(const Segment& s, fw::Nanos t) const {
  if (t <= s.t0) return (s.b - s.a) * 1e9 / static_cast<double>(tau_);
  const double x = static_cast<double>(t - s.t0) / static_cast<double>(tau_);
  if (x > 60.0) return 0.0;
  // d/ds [(a + b s) e^-s] = (b - a - b s) e^-s ; per second: / tau
  return (s.b - s.a - s.b * x) * std::exp(-x) * 1e9 / static_cast<double>(tau_);
}

const SimMirror::Segment& SimMirror::segment_for(fw::Nanos t) const {
  std::size_t i = head_;
  for (std::size_t k = 0; k + 1 < count_; ++k) {
    if (seg_[i].t0 <= t) return seg_[i];
    i = (i + kHistory - 1) % kHistory;
  }
  return seg_[i];
}

void SimMirror::command(fw::Nanos t, double target) {
  const Segment& cur = segment_for(t);
  const double x = eval(cur, t);
  // Velocity in units of steps per tau, so the new segment continues position and velocity.
  const double v = eval_velocity(cur, t) * static_cast<double>(tau_) / 1e9;
  Segment s;
  s.t0 = t;
  s.target = target;
  s.a = x - target;
  s.b = v + s.a;  // x'(0) = b - a
  head_ = (head_ + 1) % kHistory;
  seg_[head_] = s;
  if (count_ < kHistory) ++count_;
}

double SimMirror::position_at(fw::Nanos t) const { return eval(segment_for(t), t); }
double SimMirror::velocity_at(fw::Nanos t) const { return eval_velocity(segment_for(t), t); }

fw::Nanos SimMirror::settle_time(double tol) const {
  const Segment& s = seg_[head_];
  // |(a + b x) e^-x| <= (|a| + |b| x) e^-x; step x until below tol (bounded search).
  double x = 0.0;
  for (int i = 0; i < 4000; ++i, x += 0.02) {
    if ((std::abs(s.a) + std::abs(s.b) * x) * std::exp(-x) <= tol) break;
  }
  return s.t0 + static_cast<fw::Nanos>(x * static_cast<double>(tau_));
}

bool SimMirror::settled_at(fw::Nanos t, double tol) const {
  if (t < seg_[head_].t0) return std::abs(position_at(t) - segment_for(t).target) <= tol;
  return t >= settle_time(tol);
}

}  // namespace fs::sim
