#pragma once
// fw::Galvo over step/dir/enable GPIO lines (any fw::GpioLines: libgpiod or the hw-sim twin).
//
// Non-blocking: poll() emits at most one step pulse per call and never faster than max_step_rate. A move is
// in position once settle_time has passed since its last pulse. Homing drives toward negative steps until
// the home switch closes (edge event or level), sets the position to home_position, backs off
// home_backoff steps and checks that the switch opened again (a switch stuck closed is caught here); more
// than home_range steps without the switch -> HomeNotFound. With a position sensor (GpioLines::
// read_position) the position is checked once settled: no motion at all over a commanded move -> Stall,
// a residual error > position_tolerance -> MissedSteps.
#include <cstdint>

#include "firmware/device/galvo.hpp"
#include "firmware/device/gpio_lines.hpp"

namespace fs::fw {

struct StepperGalvoParams {
  double max_step_rate = 20'000.0;   // steps per second
  Nanos settle_time = 1'000'000;     // after the last pulse of a move
  std::int32_t home_position = -20;  // step value at the home switch
  std::int32_t home_range = 2000;    // steps searched before HomeNotFound
  std::int32_t home_backoff = 5;
  double position_tolerance = 0.5;  // steps
};

class StepperGalvo final : public Galvo {
 public:
  explicit StepperGalvo(GpioLines& lines, StepperGalvoParams params = {});

  void enable(Nanos now) override;
  void start_homing(Nanos now) override;
  void move_to(std::int32_t step, Nanos now) override;
  GalvoStatus poll(Nanos now) override;
  void reset_fault(Nanos now) override;
  void disable() noexcept override;

  const StepperGalvoParams& params() const { return p_; }

 private:
  enum class Phase : std::uint8_t { Idle, Moving, HomingSearch, HomingBackoff };
  void pulse(bool up, Nanos now);
  void set_fault(GalvoFault f) {
    if (fault_ == GalvoFault::None) fault_ = f;
  }

  GpioLines& lines_;
  StepperGalvoParams p_;
  Nanos min_interval_;
  Phase phase_ = Phase::Idle;
  bool enabled_ = false, homed_ = false, has_sensor_ = false;
  std::int32_t position_ = 0;  // commanded counter (steps issued)
  std::int32_t target_ = 0;
  std::int32_t search_steps_ = 0;
  double move_start_measured_ = 0.0;
  std::int32_t move_start_pos_ = 0;
  double measured_ = 0.0;
  Nanos last_pulse_ = -(1LL << 60);
  bool checked_ = true;
  GalvoFault fault_ = GalvoFault::None;
  bool dir_ = false;
};

}  // namespace fs::fw
