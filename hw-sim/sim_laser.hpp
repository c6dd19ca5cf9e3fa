#pragma once
// Twin of the laser line generator's enable line. Logs every command with its timestamp together with the
// physical emission state (which differs from the command while the laser.stuck fault is active), so tests
// can check the interlock. The emission monitor (Laser::monitor) reports the physical state.
#include <cstdint>
#include <vector>

#include "firmware/device/laser.hpp"
#include "hw-sim/sim_faults.hpp"

namespace fs::sim {

struct LaserEvent {
  fw::Nanos t = 0;
  bool commanded = false;
  bool emitting = false;
  bool forced = false;  // force_off() (exit / fault path)
};

class SimLaser final : public fw::Laser {
 public:
  explicit SimLaser(FaultScript* faults = nullptr, std::size_t log_capacity = 1 << 16);

  void set(bool on, fw::Nanos now) override;
  bool is_on() const override { return commanded_; }
  void force_off() noexcept override;
  bool monitor(bool& emitting) const override {
    emitting = emitting_;
    return true;
  }

  bool emitting() const { return emitting_; }
  // Physical emission at time t according to the log (false before the first event).
  bool emitting_at(fw::Nanos t) const;
  // Fraction of [t0, t1] during which the laser emitted.
  double on_fraction(fw::Nanos t0, fw::Nanos t1) const;
  // Every command in time order (reserved up front; log_overflow() when the capacity was exceeded).
  const std::vector<LaserEvent>& log() const { return log_; }
  bool log_overflow() const { return overflow_; }
  std::uint64_t switch_ons() const { return switch_ons_; }
  // The time used for force_off() entries (the last time seen by set()); tests may update it.
  void set_time_hint(fw::Nanos t) { last_t_ = t; }

 private:
  void record(fw::Nanos t, bool forced) noexcept;

  FaultScript* faults_;
  std::vector<LaserEvent> log_;
  std::size_t capacity_;
  bool overflow_ = false;
  bool commanded_ = false, emitting_ = false;
  std::uint64_t switch_ons_ = 0;
  fw::Nanos last_t_ = 0;
};

}  // namespace fs::sim
