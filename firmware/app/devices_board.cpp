// make_devices of facetscan-fw, the board binary: the real backends only. The simulated devices (sim,
// sim-can, --camera sim, --fault, sim-frame) are in facetscan-fw-hil (hw-sim/devices_hil.cpp); here they
// are a clear error.
#include <CLI/CLI.hpp>

#include <memory>
#include <string>

#include "common/error.hpp"
#include "firmware/app/devices.hpp"

namespace fs::fw {

namespace {

constexpr const char* kInHil =
    "the simulated devices (--galvo sim / sim-can, --camera sim, --scene, --fault, --virtual-time) are in "
    "facetscan-fw-hil; this board binary has the real backends only";

struct BoardDevices final : ScanDevices {
  RealDevices real;
};

}  // namespace

std::unique_ptr<ScanDevices> make_devices(FwConfig& cfg) {
  if (is_sim_galvo(cfg.galvo)) throw Error("--galvo '" + cfg.galvo + "': " + kInHil);
  if (is_sim_camera(cfg.camera)) throw Error("--camera '" + cfg.camera + "': " + kInHil);
  if (!cfg.faults.empty()) throw Error("--fault '" + cfg.faults.front() + "': " + kInHil);
  if (!cfg.scene.empty()) throw Error("--scene '" + cfg.scene + "': " + kInHil);
  // Virtual time is the twins' clock: the real devices run on the monotonic clock only.
  if (cfg.virtual_time.value_or(false)) throw Error(std::string("--virtual-time: ") + kInHil);
  auto d = std::make_unique<BoardDevices>();
  d->virtual_time = false;
  d->calibration = ScannerCalibration::bench_default(cfg.loop.steps);
  cfg.loop.max_rows = d->calibration.camera.height;
  RealDevices& r = d->real;
  if (!r.open_galvo(cfg.galvo))
    throw Error("--galvo '" + cfg.galvo +
                "': expected gpio:... or can:... (sim and sim-can: facetscan-fw-hil)");
  if (!r.open_camera(cfg.camera))
    throw Error("--camera '" + cfg.camera + "': expected v4l2:... (sim: facetscan-fw-hil)");
  r.open_laser(cfg.laser);
  if (!r.laser)
    throw Error("no laser line: give --laser gpio:CHIP:line=L (or laser=LINE in the --galvo gpio spec)");
  d->clock = &r.clock;
  d->galvo = r.galvo.get();
  d->camera = r.camera.get();
  d->laser = r.laser.get();
  return d;
}

CheckReport check_configured_devices(const FwConfig& cfg) {
  return check_devices(cfg.galvo, cfg.camera, cfg.laser);
}

// sim-frame (the scene renderer) is facetscan-fw-hil's: a hidden stand-in gives the clear error (exit 1)
// instead of an unknown-argument one.
bool has_twins() { return false; }

const char* program_name() { return "facetscan-fw"; }

void add_device_commands(CLI::App& app) {
  CLI::App* sub = app.add_subcommand("sim-frame", "")->group("")->prefix_command();
  sub->callback([] { throw Error("sim-frame renders simulated frames: it is in facetscan-fw-hil"); });
}

}  // namespace fs::fw
