#pragma once
// The galvo mirror. Non-blocking: commands start motions, poll() services the device and reports.
// Backends: GPIO step/dir (firmware/backends/gpio_*), CiA 402 drive over SocketCAN (firmware/backends/can_*),
// and the twins in hw-sim/.
#include <cstdint>

#include "firmware/device/clock.hpp"

namespace fs::fw {

enum class GalvoFault : std::uint8_t {
  None = 0,
  Stall,         // position does not follow the command
  MissedSteps,   // position error beyond tolerance after a move
  HomeNotFound,  // home switch not seen within the homing range/time
  DriveFault,    // drive reports a fault (CiA 402 fault bit)
  CommLost,      // no response / heartbeat lost
  BusOff,        // CAN controller bus-off
};

const char* to_string(GalvoFault f);

struct GalvoStatus {
  std::int32_t commanded_step = 0;
  double measured_step = 0.0;  // position read back (steps; fractional for encoders)
  bool moving = false;         // a commanded motion is in progress
  bool in_position = false;    // target reached and settled
  bool homed = false;
  bool enabled = false;
  GalvoFault fault = GalvoFault::None;
};

class Galvo {
 public:
  virtual ~Galvo() = default;
  virtual void enable(Nanos now) = 0;
  virtual void start_homing(Nanos now) = 0;
  virtual void move_to(std::int32_t step, Nanos now) = 0;
  virtual GalvoStatus poll(Nanos now) = 0;
  virtual void reset_fault(Nanos now) = 0;
  // Safe state (drive disabled / enable line off). noexcept: used on fault and exit paths.
  virtual void disable() noexcept = 0;
};

}  // namespace fs::fw
