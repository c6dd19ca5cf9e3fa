#pragma once
// Last line of the laser interlock: at process exit and on a crash the laser line goes to its safe level
// and the galvo is disabled. install_safety_handlers() registers the devices and handlers for SIGSEGV,
// SIGBUS, SIGFPE, SIGILL, SIGABRT (force off, then re-raise with the default action) and SIGINT/SIGTERM/
// SIGHUP (ask the controller to stop: it faults with Stopped, switches everything off and sends ScanEnd).
// SafetyGuard does the same from its destructor (normal exit, exceptions).
#include "firmware/device/galvo.hpp"
#include "firmware/device/laser.hpp"

namespace fs::fw {

class Controller;

void install_safety_handlers(Laser* laser, Galvo* galvo, Controller* controller);
void clear_safety_handlers();
// Forces the registered devices safe now (what the crash handler does). Async-signal-safe as long as the
// devices' force_off()/disable() are (GPIO ioctl, CAN write: they are).
void force_safe() noexcept;

class SafetyGuard {
 public:
  SafetyGuard(Laser& laser, Galvo& galvo, Controller* controller = nullptr) {
    install_safety_handlers(&laser, &galvo, controller);
  }
  ~SafetyGuard() {
    force_safe();
    clear_safety_handlers();
  }
  SafetyGuard(const SafetyGuard&) = delete;
  SafetyGuard& operator=(const SafetyGuard&) = delete;
};

}  // namespace fs::fw
