#pragma once
// GpioLines on a GPIO character device through libgpiod (consumer "facetscan"). The implementation is chosen
// at configure time from the installed libgpiod: gpiod_lines_v1.cpp (1.6, v1 API) or gpiod_lines_v2.cpp
// (2.x).
//   v2: step, dir, enable, laser (outputs) and home (input, both edges, CLOCK_MONOTONIC event timestamps) in
//   one
//       request. v1: the v1 uAPI cannot mix outputs and event inputs in one request, so the outputs are one
//       bulk request (always written together, as the v1 handle ioctl sets every line of the handle) and home
//       is an event request.
// set_enable(true) means "driver enabled" (the physical level follows en_active_low); safe() = step low,
// enable off, laser off; the destructor calls safe() before releasing the lines.
#include <cstdint>
#include <memory>
#include <string>

#include "common/monotonic_time.hpp"
#include "firmware/backends/factory.hpp"
#include "firmware/device/gpio_lines.hpp"
#include "firmware/device/laser.hpp"

namespace fs::fw {

class GpiodLines : public GpioLines {
 public:
  // Throws fs::Error naming the chip/line and the failed libgpiod call.
  static std::shared_ptr<GpiodLines> open(const GpioSpec& spec);
  static int api_version();  // 1 or 2 (0: built without libgpiod)

  virtual bool has_laser() const = 0;
  virtual void set_laser(bool on, Nanos now) = 0;
  virtual bool laser_on() const = 0;
  // File descriptor that becomes readable when a home edge is pending (for poll()).
  virtual int home_event_fd() const = 0;
  // Rising step edges written since open (diagnostics; the stepper galvo counts its own).
  virtual std::uint64_t step_pulses() const = 0;
  // CLOCK_MONOTONIC time right after the last line write.
  virtual Nanos last_write() const = 0;
  virtual std::string describe() const = 0;  // "gpiochip1 [label]: step=3 dir=4 en=5 home=6 laser=7"
};

// Laser enable on a line of a GpiodLines request.
class GpiodLaser final : public Laser {
 public:
  explicit GpiodLaser(std::shared_ptr<GpiodLines> lines) : lines_(std::move(lines)) {}
  ~GpiodLaser() override { force_off(); }
  void set(bool on, Nanos now) override { lines_->set_laser(on, now); }
  bool is_on() const override { return lines_->laser_on(); }
  void force_off() noexcept override {
    try {
      lines_->set_laser(false, 0);
    } catch (...) {
    }
  }

 private:
  std::shared_ptr<GpiodLines> lines_;
};

// A laser enable on its own line (gpiod_lines_v1.cpp / _v2.cpp). Throws fs::Error.
std::unique_ptr<Laser> open_gpiod_laser(const GpioLaserSpec& spec);

// CLOCK_MONOTONIC now, in ns.
inline Nanos monotonic_now() { return fs::monotonic_ns(); }

}  // namespace fs::fw
