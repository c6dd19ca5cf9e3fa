// RealDevices (firmware/app/devices.hpp): the board's galvo, camera and laser from their spec strings,
// through the backends' factory (firmware/backends/factory.hpp). Shared by both binaries' make_devices.
#include <memory>
#include <string>

#include "common/error.hpp"
#include "firmware/app/devices.hpp"
#include "firmware/backends/factory.hpp"
#include "firmware/galvo/stepper_galvo.hpp"

namespace fs::fw {

bool RealDevices::open_galvo(const std::string& spec) {
  if (spec.rfind("gpio:", 0) == 0) {
    auto b = make_gpio_backend(spec);
    lines = std::move(b.lines);
    laser = std::move(b.laser);
    galvo = std::make_unique<StepperGalvo>(*lines);
    return true;
  }
  if (spec.rfind("can:", 0) == 0) {
    galvo = make_can_galvo(spec);
    return true;
  }
  return false;
}

bool RealDevices::open_camera(const std::string& spec) {
  if (spec.rfind("v4l2:", 0) != 0) return false;
  camera = make_v4l2_camera(spec);
  return true;
}

void RealDevices::open_laser(const std::string& spec) {
  if (spec.empty()) return;
  if (laser)
    throw Error("--laser '" + spec + "': the --galvo gpio spec already has a laser= line; give only one");
  if (spec.rfind("gpio:", 0) != 0)
    throw Error("--laser '" + spec + "': expected gpio:CHIP:line=L[,active_low=1]");
  laser = make_gpio_laser(spec);
}

}  // namespace fs::fw
