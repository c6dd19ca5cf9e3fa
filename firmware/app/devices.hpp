#pragma once
// The devices of a scan, built from the configuration: one interface for the firmware's main
// (firmware/main.cpp, run_scan) and one implementation per binary, chosen at link time:
//   facetscan-fw       firmware/app/devices_board.cpp: the real backends only (libgpiod GPIO lines,
//                      SocketCAN + CiA 402, V4L2); sim, sim-can and --camera sim are a clear error naming
//                      facetscan-fw-hil
//   facetscan-fw-hil   hw-sim/devices_hil.cpp: the twins (sim, sim-can, --camera sim with its scene and
//                      calibration, --fault), and the board's RealDevices (below) for every real spec
// Memory: everything is built once before the scan (heap allocations here are fine); a ScanDevices owns
// all that its pointers point at and must outlive the Controller, the SafetyGuard and the publisher.
#include <memory>
#include <string>

#include "common/calibration.hpp"
#include "firmware/backends/device_check.hpp"
#include "firmware/device/camera.hpp"
#include "firmware/device/clock.hpp"
#include "firmware/device/galvo.hpp"
#include "firmware/device/gpio_lines.hpp"
#include "firmware/device/laser.hpp"
#include "firmware/fw_config.hpp"
#include "firmware/loop/controller.hpp"
#include "firmware/loop/monotonic_clock.hpp"

namespace CLI {
class App;
}

namespace fs::fw {

class ScanDevices {
 public:
  virtual ~ScanDevices() = default;

  Clock* clock = nullptr;
  Galvo* galvo = nullptr;
  Laser* laser = nullptr;
  Camera* camera = nullptr;
  ScannerCalibration calibration;  // of the camera and laser the scan runs with
  bool virtual_time = false;       // the clock is simulated (runs as fast as the loop)

  Devices devices() const { return Devices{*clock, *galvo, *laser, *camera}; }
};

// Opens the devices cfg names (galvo, camera, laser; scene, faults, sim_camera on the HIL side). Fills in
// cfg.loop.max_rows (and steps / first_step from a simulated scene). Throws fs::Error naming the spec.
std::unique_ptr<ScanDevices> make_devices(FwConfig& cfg);

// `--check`: probes the configured devices without moving anything.
CheckReport check_configured_devices(const FwConfig& cfg);

// Subcommands of this binary besides the scan (facetscan-fw-hil: sim-frame; facetscan-fw: none).
void add_device_commands(CLI::App& app);

// Whether this binary has the twins (facetscan-fw-hil) or the real backends only (facetscan-fw): the help
// lists the simulated devices and the twins' options only where they work.
bool has_twins();

// This binary's name, for --version, the help and the prefix of its messages: "facetscan-fw" or
// "facetscan-fw-hil".
const char* program_name();

// The real devices of the board (facetscan-fw's make_devices; facetscan-fw-hil's for real specs). Destroyed
// in reverse member order: the laser first, the clock last.
struct RealDevices {
  MonotonicClock clock;
  std::unique_ptr<Galvo> galvo;
  std::unique_ptr<Camera> camera;
  std::shared_ptr<GpioLines> lines;  // of a gpio: galvo
  std::shared_ptr<Laser> laser;      // the gpio: galvo's laser= line or --laser

  // --galvo gpio:... (StepperGalvo on the lines, with its laser= line) or can:... (CiA 402 master);
  // false (nothing opened) for any other spec.
  bool open_galvo(const std::string& spec);
  // --camera v4l2:...; false for any other spec.
  bool open_camera(const std::string& spec);
  // --laser gpio:CHIP:line=L[,active_low=1] (none when empty); an error when the galvo spec had laser= too.
  void open_laser(const std::string& spec);
};

}  // namespace fs::fw
