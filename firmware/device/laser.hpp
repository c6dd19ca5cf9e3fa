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
};

}  // namespace fs::fw
