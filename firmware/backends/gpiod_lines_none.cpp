// Built without libgpiod: the GPIO galvo backend reports a clear error.
#include <time.h>

#include "common/error.hpp"
#include "firmware/backends/gpiod_lines.hpp"

namespace fs::fw {

std::shared_ptr<GpiodLines> GpiodLines::open(const GpioSpec& spec) {
  throw Error("GPIO chip '" + spec.chip +
              "': facetscan-fw was built without libgpiod (install libgpiod-dev)");
}
int GpiodLines::api_version() { return 0; }
std::unique_ptr<Laser> open_gpiod_laser(const GpioLaserSpec& spec) {
  throw Error("GPIO chip '" + spec.chip +
              "': facetscan-fw was built without libgpiod (install libgpiod-dev)");
}

}  // namespace fs::fw
