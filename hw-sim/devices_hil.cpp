// make_devices of facetscan-fw-hil (firmware/app/devices.hpp): the board firmware's controller loop on the
// twins. Handles the simulated devices: `--galvo sim` (the firmware's StepperGalvo on the stepper-lines
// twin), `--galvo sim-can` (the firmware's CiA 402 master on the drive twin), `--camera sim` (the scene
// renderer, whose scanner geometry becomes the calibration) and `--fault`; hands every real spec (gpio:,
// can:, v4l2:, --laser) to the board's RealDevices, so mixed setups (sim-can with a V4L2 camera and a GPIO
// laser) work as on the board. Adds the `sim-frame` subcommand.
#include <CLI/CLI.hpp>

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "common/error.hpp"
#include "firmware/app/devices.hpp"
#include "firmware/backends/can_port.hpp"
#include "firmware/backends/factory.hpp"
#include "hw-sim/can/cia402_twin.hpp"
#include "hw-sim/can/sim_can_galvo.hpp"
#include "hw-sim/scene/scene.hpp"
#include "hw-sim/scene/sim_frame_cli.hpp"
#include "hw-sim/scene/stripe_renderer.hpp"
#include "hw-sim/scene_frame_renderer.hpp"
#include "hw-sim/sim_rig.hpp"

namespace fs::fw {
namespace {

bool starts_with(const std::string& s, const char* p) { return s.rfind(p, 0) == 0; }

std::string default_scene() {
  const std::filesystem::path src = FACETSCAN_DEFAULT_SCENE;
  if (std::filesystem::exists(src)) return src.string();
  return "hw-sim/scenes/default.json";
}

// Destroyed in reverse member order: the real devices (a sim-can galvo's last twin poll still moves the rig's
// mirror) before the rig, the rig before its renderer, the renderer before the scene it draws.
struct HilDevices final : ScanDevices {
  sim::Scene scene;
  std::unique_ptr<sim::SceneFrameRenderer> renderer;
  std::unique_ptr<sim::SimRig> rig;
  RealDevices real;
};

// The scene and its calibration for the simulated camera (the same sweep in another number of steps with
// --steps); sets cfg.loop.steps / first_step from it.
void load_scene(HilDevices& d, FwConfig& cfg) {
  const std::string path = cfg.scene.empty() ? default_scene() : cfg.scene;
  d.scene = sim::load_scene(path);
  ScannerCalibration& cal = d.calibration;
  cal = d.scene.calibration;
  if (cfg.steps_given && cal.step_count != cfg.loop.steps) {
    const double a0 = cal.laser.mirror_angle(cal.first_step);
    const double a1 = cal.laser.mirror_angle(cal.first_step + static_cast<double>(cal.step_count) - 1.0);
    cal.laser.mirror_angle_at_step0 = a0;
    cal.laser.rad_per_step = cfg.loop.steps > 1 ? (a1 - a0) / (cfg.loop.steps - 1.0) : 0.0;
    cal.first_step = 0;
    cal.step_count = cfg.loop.steps;
    d.scene.calibration = cal;
  }
  if (!cfg.steps_given) cfg.loop.steps = cal.step_count;
  cfg.loop.first_step = cal.first_step;
  std::fprintf(stderr, "%s: scene %s (%zu objects), %u steps\n", program_name(), path.c_str(),
               d.scene.objects.size(), cfg.loop.steps);
}

void check_sim_can(CheckReport& r, const std::string& device, const CanSpec& cs) {
  MonotonicClock clock;
  const auto fds = CanPort::socketpair_fds();
  CanPort port(fds[0], true);
  sim::Cia402TwinConfig tc;
  tc.node = cs.node;
  sim::Cia402Twin twin(fds[1], clock, tc);
  r.add(device, "CAN (sim-can)", true, "hw-sim CiA 402 drive twin over a socketpair");
  check_can_drive(
      r, device, "the socketpair", port, cs.node, clock, [&] { twin.poll(); }, 300'000'000);
  ::close(fds[1]);
}

}  // namespace

std::unique_ptr<ScanDevices> make_devices(FwConfig& cfg) {
  const bool sim_galvo = is_sim_galvo(cfg.galvo);
  const bool sim_camera = is_sim_camera(cfg.camera);
  if (!sim_galvo && !starts_with(cfg.galvo, "gpio:") && !starts_with(cfg.galvo, "can:"))
    throw Error("--galvo '" + cfg.galvo + "': expected sim, sim-can[:...], gpio:... or can:...");
  // The galvo faults act on the step/dir lines' twin; the CAN drive twin has none of its own (as demo says).
  for (const auto& f : cfg.faults)
    if (cfg.galvo != "sim" && starts_with(f, "galvo."))
      throw Error("--fault '" + f + "': galvo faults act on the step/dir GPIO twin (--galvo sim); --galvo '" +
                  cfg.galvo + "' takes camera.* and laser.* faults");
  if (sim_camera && !sim_galvo)
    throw Error("--camera sim renders for the simulated mirror: use it with --galvo sim or sim-can");
  if (!sim_camera && sim_galvo && cfg.galvo == "sim")
    throw Error("--galvo sim drives a simulated mirror that a real camera cannot see; use --camera sim");
  auto d = std::make_unique<HilDevices>();
  d->virtual_time = cfg.virtual_time.value_or(sim_galvo && sim_camera);
  d->calibration = ScannerCalibration::bench_default(cfg.loop.steps);
  if (sim_camera) load_scene(*d, cfg);
  cfg.loop.max_rows = d->calibration.camera.height;

  sim::RigConfig rc;
  rc.realtime = !d->virtual_time;
  rc.faults = cfg.faults;
  rc.camera.frame_period = static_cast<Nanos>(cfg.sim_period_us) * 1000;
  rc.camera.exposure = static_cast<Nanos>(cfg.sim_exposure_us) * 1000;
  rc.camera.readout = static_cast<Nanos>(cfg.sim_readout_us) * 1000;
  rc.camera.buffers = cfg.sim_buffers;
  if (sim_camera) {
    static_assert(kMaxSimSpeckleGrainPx == sim::kMaxSpeckleGrainPx);
    sim::RenderOptions ro;
    ro.speckle_grain_px = cfg.sim_speckle_grain_px;
    d->renderer = std::make_unique<sim::SceneFrameRenderer>(d->scene, ro);
    d->rig = std::make_unique<sim::SimRig>(*d->renderer, rc);
  } else if (!cfg.faults.empty()) {
    throw Error("--fault needs the simulated devices (--galvo sim --camera sim)");
  }
  if (sim_camera && !cfg.laser.empty())
    throw Error("--laser '" + cfg.laser +
                "': the simulated camera sees the simulated laser; use --laser with --camera v4l2:...");

  sim::SimRig* rig = d->rig.get();
  RealDevices& real = d->real;
  d->clock = rig ? static_cast<Clock*>(&rig->clock) : &real.clock;
  d->laser = rig ? &rig->laser : nullptr;
  d->camera = rig ? &rig->camera : nullptr;
  if (cfg.galvo == "sim") {
    d->galvo = &rig->galvo;
  } else {
    if (starts_with(cfg.galvo, "sim-can")) {
      auto b = sim::make_sim_can_galvo(cfg.galvo, *d->clock);
      real.galvo = std::move(b.galvo);
      if (rig) {
        sim::SimMirror* mirror = &rig->mirror;
        b.twin->set_position_callback([mirror](double pos, std::int64_t t) { mirror->command(t, pos); });
      }
    } else {
      real.open_galvo(cfg.galvo);  // gpio: or can: (any other spec was refused at the top)
    }
    d->galvo = real.galvo.get();
    if (!sim_camera) {
      if (!real.open_camera(cfg.camera))
        throw Error("--camera '" + cfg.camera + "': expected sim or v4l2:...");
      d->camera = real.camera.get();
    }
    real.open_laser(cfg.laser);
    if (!d->laser) d->laser = real.laser.get();
  }
  if (!d->laser)
    throw Error("no laser line: give --laser gpio:CHIP:line=L (or laser=LINE in the --galvo gpio spec)");
  return d;
}

CheckReport check_configured_devices(const FwConfig& cfg) {
  SimChecks sim;
  sim.galvo = [](CheckReport& r, const std::string& spec) {
    if (spec == "sim")
      r.add("galvo", "sim", true, "hw-sim stepper twin (no hardware)");
    else
      check_sim_can(r, "galvo", parse_can_spec(spec));
  };
  sim.camera = [](CheckReport& r, const std::string&) {
    r.add("camera", "sim", true, "hw-sim camera twin rendering the scene (no hardware)");
  };
  return check_devices(cfg.galvo, cfg.camera, cfg.laser, sim);
}

bool has_twins() { return true; }

const char* program_name() { return "facetscan-fw-hil"; }

void add_device_commands(CLI::App& app) { sim::add_sim_frame_command(app); }

}  // namespace fs::fw
