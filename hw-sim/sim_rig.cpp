#include "hw-sim/sim_rig.hpp"

namespace fs::sim {

namespace {
FaultScript make_script(const std::vector<std::string>& specs, fw::Nanos t0) {
  FaultScript s;
  for (const auto& text : specs) s.add(parse_fault_spec(text));
  s.set_start(t0);
  return s;
}
}  // namespace

SimRig::SimRig(FrameRenderer& renderer, RigConfig cfg)
    : clock(cfg.start_time, cfg.realtime),
      faults(make_script(cfg.faults, clock.now())),
      mirror(static_cast<double>(cfg.stepper.start_position), cfg.mirror_tau),
      lines(mirror, &faults, cfg.stepper),
      galvo(lines,
            [&] {
              fw::StepperGalvoParams g = cfg.galvo;
              g.home_position = static_cast<std::int32_t>(cfg.stepper.home_position);
              return g;
            }()),
      laser(&faults),
      camera(clock, mirror, laser, renderer, &faults, cfg.camera) {}

}  // namespace fs::sim
