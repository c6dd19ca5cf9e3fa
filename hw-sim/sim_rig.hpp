#pragma once
// The whole simulated scanner in one object: clock, fault script, mirror, stepper-lines twin + the
// firmware's StepperGalvo on it, laser twin, renderer, camera twin. What `--galvo sim --camera sim` and
// the HIL tests run on. The renderer is supplied by the caller (TableStripeRenderer or the scene
// renderer adapter) and must outlive the rig.
#include <memory>
#include <string>
#include <vector>

#include "common/calibration.hpp"
#include "firmware/galvo/stepper_galvo.hpp"
#include "hw-sim/frame_renderer.hpp"
#include "hw-sim/sim_camera.hpp"
#include "hw-sim/sim_clock.hpp"
#include "hw-sim/sim_faults.hpp"
#include "hw-sim/sim_laser.hpp"
#include "hw-sim/sim_mirror.hpp"
#include "hw-sim/sim_stepper.hpp"

namespace fs::sim {

struct RigConfig {
  bool realtime = false;
  fw::Nanos start_time = 1'000'000'000;
  fw::Nanos mirror_tau = 100'000;
  StepperTwinParams stepper;
  fw::StepperGalvoParams galvo;
  CameraTwinParams camera{5'000'000, 1'000'000, 1'000'000, 0, 4};
  std::vector<std::string> faults;  // fault specs (hw-sim/sim_faults.hpp)
};

class SimRig {
 public:
  SimRig(FrameRenderer& renderer, RigConfig cfg = {});

  SimClock clock;
  FaultScript faults;
  SimMirror mirror;
  SimStepperLines lines;
  fw::StepperGalvo galvo;
  SimLaser laser;
  SimCamera camera;
};

}  // namespace fs::sim
