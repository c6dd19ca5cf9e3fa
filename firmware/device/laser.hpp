#pragma once
// The laser line generator's enable. off() must be safe to call from any state, any number of times.
#include "firmware/device/clock.hpp"

namespace fs::fw {

class Laser {
 public:
  virtual ~Laser() = default;
  virtual void set(bool on, Nanos now) = 0;
  virtual bool is_on() const = 0;
  // Drive the line to its safe level (off) without touching anything else; noexcept for exit/fault paths.
  virtual void force_off() noexcept = 0;
  // Optional emission monitor (photodiode / current sense). Returns false when the hardware has none;
  // otherwise sets `emitting` to the measured state. The controller faults when it disagrees with is_on().
  virtual bool monitor(bool& emitting) const {
    (void)emitting;
    return false;
  }
};

}  // namespace fs::fw
