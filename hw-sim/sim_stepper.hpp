#pragma once
// Twin of a step/dir/enable stepper driver with a home switch (implements fw::GpioLines).
//
// A rising step edge while enabled moves the motor one step in the direction of the dir line (dir high =
// +1) unless it comes sooner than min_step_interval after the previous accepted one (the motor cannot
// follow: the step is lost and counted as a rate violation), the fault script loses it (missed steps) or
// the mirror is stalled. Every edge is logged with its timestamp. The mirror (SimMirror) follows the motor
// position with its settling dynamics. The home switch is closed (read_home() true) while the motor
// position is <= home_position; each change produces an edge event for next_home_edge().
#include <array>
#include <cstdint>
#include <limits>
#include <vector>

#include "firmware/device/gpio_lines.hpp"
#include "hw-sim/sim_faults.hpp"
#include "hw-sim/sim_mirror.hpp"

namespace fs::sim {

struct StepperTwinParams {
  fw::Nanos min_step_interval = 20'000;  // 50 kHz maximum step rate
  std::int64_t home_position = -20;      // switch closed at motor positions <= this
  std::int64_t start_position = 37;      // where the motor is at power-up (unknown to the firmware)
  std::size_t edge_log_capacity = 1 << 16;
  bool position_sensor = true;  // the mirror's position detector (1/64 step resolution)
};

struct StepEdge {
  fw::Nanos t = 0;
  std::int8_t direction = 0;  // +1 / -1 accepted step, 0 lost
};

class SimStepperLines final : public fw::GpioLines {
 public:
  SimStepperLines(SimMirror& mirror, FaultScript* faults = nullptr, StepperTwinParams params = {});

  void set_step(bool level, fw::Nanos now) override;
  void set_dir(bool level, fw::Nanos now) override;
  void set_enable(bool level, fw::Nanos now) override;
  bool read_home(fw::Nanos now) override;
  bool next_home_edge(fw::GpioEdge& edge) override;
  void safe() noexcept override;
  bool read_position(double& steps, fw::Nanos now) override;

  std::int64_t motor_position() const { return position_; }
  bool enabled() const { return enable_; }
  std::uint32_t rate_violations() const { return rate_violations_; }
  std::uint32_t lost_steps() const { return lost_steps_; }
  std::uint64_t accepted_steps() const { return accepted_; }
  // Rising step edges (accepted and lost) in time order; capped at edge_log_capacity (edge_log_overflow()).
  const std::vector<StepEdge>& step_log() const { return log_; }
  bool edge_log_overflow() const { return log_overflow_; }
  const StepperTwinParams& params() const { return p_; }

 private:
  void update_home(fw::Nanos now);

  SimMirror& mirror_;
  FaultScript* faults_;
  StepperTwinParams p_;
  std::int64_t position_;
  bool step_ = false, dir_ = false, enable_ = false, home_closed_ = false;
  fw::Nanos last_step_ = std::numeric_limits<fw::Nanos>::min() / 2;
  std::uint32_t rate_violations_ = 0, lost_steps_ = 0;
  std::uint64_t accepted_ = 0;
  std::vector<StepEdge> log_;
  bool log_overflow_ = false;
  std::array<fw::GpioEdge, 64> edges_{};
  std::size_t edge_head_ = 0, edge_count_ = 0;
};

}  // namespace fs::sim
