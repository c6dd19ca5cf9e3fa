#pragma once
// Real device backends from the command-line spec strings of facetscan-fw:
//   --galvo gpio:CHIP:step=L,dir=L,en=L,home=L[,laser=L][,home_active_low=0|1][,en_active_low=0|1]
//        CHIP = gpiochipN, /dev/gpiochipN, a chip label or number; L = line offset or line name.
//   --galvo can:IFACE[:node=N][,hb=MS][,vel=STEPS_PER_S][,acc=STEPS_PER_S2][,sdo_ms=MS][,state_ms=MS]
//        CiA 402 drive on SocketCAN (sdo_ms: SDO timeout per attempt, default 50; state_ms: enable/homing,
//        500)
//   --galvo sim-can[:node=N][,...same keys as can]   parsed here (parse_can_spec); the master + drive
//        twin pair is built in hw-sim (hw-sim/can/sim_can_galvo.hpp, facetscan-fw-hil only)
//   --camera v4l2:/dev/videoN[:fmt=GREY|Y16|YUYV][,width=W][,height=H][,fps=F][,exposure=E][,buffers=N]
//   --laser gpio:CHIP:line=L[,active_low=1]   a laser enable on its own GPIO line (for the CAN galvo)
// Parsing errors throw fs::Error naming the spec and the offending key/value.
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "firmware/backends/cia402_master.hpp"
#include "firmware/device/camera.hpp"
#include "firmware/device/galvo.hpp"
#include "firmware/device/gpio_lines.hpp"
#include "firmware/device/laser.hpp"

namespace fs::fw {

// A GPIO line: by offset on the chip, or by name (gpio-line-names / gpio-sim "name").
struct GpioLineRef {
  int offset = -1;   // >= 0 when given as a number
  std::string name;  // non-empty when given as a name
  bool valid() const { return offset >= 0 || !name.empty(); }
};

struct GpioSpec {
  std::string chip;
  GpioLineRef step, dir, enable, home, laser;  // laser optional
  bool home_active_low = false;                // home switch closes to ground
  bool enable_active_low = false;              // driver EN pin is active low (most stepper drivers)
};

struct GpioLaserSpec {
  std::string chip;
  GpioLineRef line;
  bool active_low = false;
};

struct CanSpec {
  std::string iface;      // empty for sim-can
  std::uint8_t node = 1;  // CANopen node id 1..127
  std::uint16_t heartbeat_ms = 100;
  std::uint32_t velocity = 20000;        // profile velocity, steps/s
  std::uint32_t acceleration = 400000;   // profile acceleration = deceleration, steps/s^2
  std::uint32_t sdo_timeout_ms = 50;     // per SDO attempt (sdo_ms=)
  std::uint32_t state_timeout_ms = 500;  // enable / fault reset / homing steps (state_ms=)
};

enum class V4l2Fourcc : std::uint8_t { Grey = 0, Y16 = 1, Yuyv = 2 };

struct V4l2Spec {
  std::string device;
  V4l2Fourcc format = V4l2Fourcc::Grey;
  std::uint32_t width = 1280, height = 1024;
  std::uint32_t fps = 0;       // 0: leave the driver's rate
  std::int32_t exposure = -1;  // V4L2_CID_EXPOSURE_ABSOLUTE units (100 us); -1: leave it
  std::uint32_t buffers = 4;   // MMAP buffers, >= 4
};

GpioSpec parse_gpio_spec(std::string_view spec);             // "gpio:..."
CanSpec parse_can_spec(std::string_view spec);               // "can:..." or "sim-can..."
V4l2Spec parse_v4l2_spec(std::string_view spec);             // "v4l2:..."
GpioLaserSpec parse_gpio_laser_spec(std::string_view spec);  // "gpio:CHIP:line=L[,active_low=1]"

struct GpioBackend {
  std::shared_ptr<GpioLines> lines;  // step/dir/enable/home (build the stepper Galvo on it)
  std::unique_ptr<Laser> laser;      // null when the spec has no laser= line; keeps `lines` alive
};
// Opens the chip and requests the lines (consumer "facetscan"). Throws fs::Error.
GpioBackend make_gpio_backend(std::string_view spec);

// A laser enable line alone (one-line request, consumer "facetscan", off at start and on destruction).
std::unique_ptr<Laser> make_gpio_laser(std::string_view spec);

// Opens a raw CAN socket on IFACE and returns the CiA 402 galvo. Throws fs::Error.
std::unique_ptr<Galvo> make_can_galvo(std::string_view spec);

// The master's settings of a can: / sim-can spec.
Cia402Config cia402_config(const CanSpec& spec);

// Opens and configures the V4L2 device (capture starts at Camera::start). Throws fs::Error.
std::unique_ptr<Camera> make_v4l2_camera(std::string_view spec);

}  // namespace fs::fw
