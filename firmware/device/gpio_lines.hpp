#pragma once
// The GPIO lines of a step/dir galvo driver: outputs step, dir, enable (and laser when wired to the same
// chip), input home switch with edge events. Real: libgpiod (firmware/backends/gpiod_lines_*.cpp);
// twin: hw-sim/sim_stepper.hpp, which turns step edges into mirror motion.
#include <cstdint>

#include "firmware/device/clock.hpp"

namespace fs::fw {

struct GpioEdge {
  Nanos timestamp = 0;
  bool rising = false;
};

class GpioLines {
 public:
  virtual ~GpioLines() = default;
  virtual void set_step(bool level, Nanos now) = 0;
  virtual void set_dir(bool level, Nanos now) = 0;
  virtual void set_enable(bool level, Nanos now) = 0;
  virtual bool read_home(Nanos now) = 0;
  // Pops the next home-switch edge event; false when none is pending. Never blocks.
  virtual bool next_home_edge(GpioEdge& edge) = 0;
  // All outputs to their safe levels (enable off). noexcept.
  virtual void safe() noexcept = 0;
  // Optional mirror position sensor (galvo position detector / encoder), in steps. Returns false when none
  // is wired; then the stepper galvo runs open loop and cannot detect stalls or missed steps.
  virtual bool read_position(double& steps, Nanos now) {
    (void)steps;
    (void)now;
    return false;
  }
};

}  // namespace fs::fw
