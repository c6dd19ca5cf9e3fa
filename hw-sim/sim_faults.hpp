#pragma once
// Scriptable fault injection for the device twins.
//
// A fault spec (CLI --fault, config "faults", tests) reads
//   DEVICE.KIND[@TRIGGER][,count=N][,for=SECONDS][,level=on|off]
// with TRIGGER one of  t=SECONDS (virtual time since the twins' start), step=N (galvo: when a step pulse
// moves the motor up (the scan direction) to step N; homing passes do not count), frame=N (camera: frame
// sequence N), on=N (laser: the N-th switch-on, 0-based). Without a trigger the fault is active from the
// start.
//   galvo.missed-steps   count (default 3) step pulses are lost by the motor
//   galvo.stall          the mirror stops following the step pulses (for SECONDS, default: forever)
//   galvo.home-stuck     the home switch reads `level` (default off) whatever the mirror does
//   camera.timeout       no frame is delivered (for SECONDS, default: forever)
//   camera.drop          count (default 1) frames are lost (sequence gap)
//   camera.saturate      count (default 1) frames are rendered saturated (laser glare)
//   laser.stuck          the laser line is stuck at `level` (default on) from the trigger (for SECONDS)
// Examples: "galvo.stall@step=120", "camera.drop@frame=40,count=2", "laser.stuck@on=10".
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "firmware/device/clock.hpp"

namespace fs::sim {

enum class FaultKind : std::uint8_t {
  GalvoMissedSteps,
  GalvoStall,
  GalvoHomeStuck,
  CameraTimeout,
  CameraDrop,
  CameraSaturate,
  LaserStuck,
};
const char* to_string(FaultKind k);

enum class FaultTrigger : std::uint8_t { Always, Time, Step, Frame, LaserOn };

struct FaultSpec {
  FaultKind kind = FaultKind::GalvoStall;
  FaultTrigger trigger = FaultTrigger::Always;
  std::int64_t at = 0;      // ns for Time (relative to the script's start), index otherwise
  std::int64_t count = -1;  // pulses / frames; -1 = the kind's default
  fw::Nanos duration = -1;  // ns; -1 = forever
  bool level = false;       // home-stuck / laser-stuck level
  std::string text;         // the spec as given
};

// Throws fs::Error("fault spec 'X': ...") naming the offending part.
FaultSpec parse_fault_spec(std::string_view spec);

// The faults of one run and their progress. Each twin asks it at its events; not thread-safe (the twins are
// serviced by one thread).
class FaultScript {
 public:
  FaultScript() = default;
  explicit FaultScript(std::vector<FaultSpec> specs) : specs_(std::move(specs)), state_(specs_.size()) {}
  void add(FaultSpec spec);
  void set_start(fw::Nanos t0) { t0_ = t0; }
  bool empty() const { return specs_.empty(); }
  const std::vector<FaultSpec>& specs() const { return specs_; }

  // Galvo: a step pulse while the commanded position is `target` -> true when the pulse is lost.
  bool galvo_pulse_lost(fw::Nanos now, std::int64_t target);
  bool galvo_stalled(fw::Nanos now, std::int64_t target);
  // Home switch override: returns true and sets level when stuck.
  bool home_stuck(fw::Nanos now, std::int64_t target, bool& level);
  // Camera, for frame `sequence` exposed at `t`.
  bool camera_timeout(fw::Nanos t, std::uint32_t sequence);
  bool camera_drop(fw::Nanos t, std::uint32_t sequence);
  bool camera_saturate(fw::Nanos t, std::uint32_t sequence);
  // Laser: the line's physical level when stuck (switch_on_index = number of switch-ons so far).
  bool laser_stuck(fw::Nanos now, std::int64_t switch_on_index, bool& level);

  // When each fault first took effect (-1 = not yet); index as in specs().
  fw::Nanos fired_at(std::size_t i) const { return state_[i].fired_at; }

 private:
  struct State {
    bool armed = false;
    fw::Nanos armed_at = 0;
    std::int64_t used = 0;
    fw::Nanos fired_at = -1;
  };
  // Whether spec i is active for this event (arming it when its trigger is met).
  bool active(std::size_t i, fw::Nanos now, std::int64_t index);

  std::vector<FaultSpec> specs_;
  std::vector<State> state_;
  fw::Nanos t0_ = 0;
};

}  // namespace fs::sim
