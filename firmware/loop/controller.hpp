#pragma once
// The scanner's controller loop: Idle -> Homing -> Ready -> Scanning -> Done, Fault from anywhere.
//
// One tick per control period on absolute deadlines (Clock::sleep_until(t0 + n * period)); a tick that
// wakes later than late_limit counts as an overrun, and more than max_consecutive_late of them in a row is a
// fault. Scanning step k: command the galvo to first_step + k; once it reports in position, laser on; take
// the first camera frame whose exposure started after the laser came on (older frames are released); laser
// off; extract the stripe (firmware/extract); publish it; next step on the next tick. Camera grabs use
// deadline = now, so the loop never blocks on the camera; publishing copies into a queue (no I/O).
//
// Interlock, evaluated first in every tick: the laser may only be on while Scanning in the exposure phase
// with the galvo in position, without fault, within the dwell limit, with the loop on time and (when
// require_host) the host connected. Otherwise it is switched off in that same tick. Faults switch the laser
// off, disable the galvo, stop the camera and send a Fault message; the ScanEnd message follows.
//
// After start() no heap allocation happens in tick() (buffers are sized by the configuration).
#include <array>
#include <atomic>
#include <cstdint>
#include <vector>

#include "common/calibration.hpp"
#include "common/messages.hpp"
#include "firmware/device/camera.hpp"
#include "firmware/device/clock.hpp"
#include "firmware/device/galvo.hpp"
#include "firmware/device/laser.hpp"
#include "firmware/extract/stripe_extractor.hpp"
#include "firmware/loop/fault_codes.hpp"
#include "firmware/loop/lateness_histogram.hpp"
#include "firmware/stream/publisher.hpp"

namespace fs::fw {

enum class State : std::uint8_t { Idle = 0, Homing = 1, Ready = 2, Scanning = 3, Done = 4, Fault = 5 };
const char* to_string(State s);

struct LoopConfig {
  Nanos period = 500'000;  // control period (tick)
  std::int32_t first_step = 0;
  std::uint32_t steps = 500;
  Nanos homing_timeout = 2'000'000'000;
  Nanos move_timeout = 50'000'000;         // in-position not reached after a move command
  Nanos max_dwell = 40'000'000;            // laser on longer than this in one step -> DwellOverrun
  Nanos camera_timeout = 25'000'000;       // no frame at all for this long -> CameraTimeout
  Nanos late_limit = 250'000;              // wake-up later than this = overrun
  std::uint32_t max_consecutive_late = 3;  // more consecutive overruns -> DeadlineMissed
  Nanos heartbeat_period = 500'000'000;
  bool require_host = false;           // streaming: host connection loss is a fault
  Nanos host_grace = 0;                // ... after being lost this long
  double saturated_rows_limit = 0.05;  // fraction of stripe rows saturated -> repeat the step
  std::uint32_t saturated_retries = 2;
  std::uint32_t max_rows = 4096;  // largest image height
  std::uint64_t scan_id = 1;
  ExtractParams extract;
};

struct Devices {
  Clock& clock;
  Galvo& galvo;
  Laser& laser;
  Camera& camera;
};

// One fault as the loop saw it. For a fatal fault, the laser-off latency is measured against the laser line's
// state (its emission monitor when the laser has one, else the commanded level): from the fault's onset (the
// moment the condition arose when the loop knows it: dwell limit, camera silence, host grace, move / homing
// timeout, deadline limit; otherwise the previous tick, the last time the loop found no fault) to the clock
// reading after the line was read back off.
struct FaultEvent {
  FaultCode code = FaultCode::None;
  Nanos time = 0;   // tick that raised it
  Nanos onset = 0;  // see above
  std::uint32_t step = 0;
  State state = State::Idle;  // state when raised
  // Fatal faults: the line was already off at the onset / still emitting after the off command (stuck) /
  // otherwise off after latency_ns. Warnings do not touch the laser (latency_ns = -1).
  bool laser_already_off = false, laser_still_emitting = false;
  Nanos latency_ns = -1;
};

// Everything the loop measured, also sent in ScanEnd.
struct LoopReport {
  State state = State::Idle;
  FaultCode fault = FaultCode::None;
  Nanos fault_time = -1;
  std::uint32_t fault_count = 0;  // fatal + warnings
  std::uint32_t stripes_sent = 0, frames_captured = 0, frames_dropped = 0, frames_stale = 0;
  std::uint32_t stripes_dropped = 0, saturated_retries = 0;
  std::uint32_t overruns = 0;
  std::uint64_t ticks = 0;
  LatenessHistogram lateness;
  // The ticks whose thread slept until the deadline (the previous tick had finished before it): their
  // lateness is the wake-up latency alone, what cyclictest measures. The others started late because the
  // previous tick's work ran past the deadline (counted in ticks_without_sleep, included in `lateness`).
  LatenessHistogram wakeup;
  std::uint64_t ticks_without_sleep = 0;
  Nanos extract_total_ns = 0, extract_max_ns = 0;
  std::uint32_t extractions = 0;
  // The first kMaxFaultEvents faults (fatal and warnings); fault_count counts them all.
  static constexpr std::size_t kMaxFaultEvents = 16;
  std::array<FaultEvent, kMaxFaultEvents> fault_events{};
  std::uint32_t fault_events_n = 0;
  // Largest laser-off latency of the fatal faults (-1: none measured).
  Nanos max_laser_off_latency_ns = -1;
  msg::LoopStats stats() const;
};

// "laser off after 0.50 ms (period 0.50 ms)", "laser already off", "laser line still emitting after the off
// command": the latency part of the Fault message and the summary.
int format_laser_off(char* buf, std::size_t n, const FaultEvent& e, Nanos period);

class Controller {
 public:
  Controller(Devices dev, const LoopConfig& cfg, Publisher& pub, const ScannerCalibration& cal);
  ~Controller();  // laser forced off, galvo disabled

  // Homing starts; ScanBegin is published. Time origin of the deadlines = now.
  void start();
  // One control period's work (called by run() after each deadline; tests may call it directly).
  void tick(Nanos now);
  // start(), loop(), finish().
  const LoopReport& run();
  // Ticks on absolute deadlines (t0 + n * period) until Done or Fault.
  void loop();
  // Sleeps until the next deadline and runs that tick (lateness recorded). Returns false once Done / Fault.
  bool run_one();
  // Sends ScanEnd (once) and leaves every device safe.
  void finish();
  // Asynchronous stop request (signal handler safe): the loop faults with Stopped at its next tick.
  void request_stop() { stop_requested_.store(true, std::memory_order_relaxed); }

  State state() const { return report_.state; }
  const LoopReport& report() const { return report_; }
  const LoopConfig& config() const { return cfg_; }
  std::uint32_t current_step() const { return step_; }

 private:
  enum class Phase : std::uint8_t { Move, WaitInPosition, Expose };
  // onset < 0: the previous tick (see FaultEvent).
  void fault(FaultCode code, Nanos now, Nanos onset = -1);
  bool line_emitting() const;  // the laser line's state: emission monitor, else the commanded level
  FaultEvent* new_event(FaultCode code, Nanos now);
  void warn(FaultCode code, Nanos now, const char* detail);
  void set_laser(bool on, Nanos now);
  void account_frame(const FrameView& f, Nanos now);  // sequence gaps, camera liveness
  bool handle_frame(const FrameView& f, Nanos now);   // true when the step's frame was taken
  void record_lateness(Nanos lateness);

  Devices dev_;
  LoopConfig cfg_;
  Publisher& pub_;
  ScannerCalibration cal_;
  LoopReport report_;
  Phase phase_ = Phase::Move;
  std::uint32_t step_ = 0;
  std::uint32_t retries_ = 0;
  Nanos t0_ = 0, state_since_ = 0, phase_since_ = 0, laser_on_at_ = -1, last_frame_at_ = 0,
        last_heartbeat_ = 0;
  Nanos host_lost_since_ = -1;
  Nanos prev_tick_ = 0, last_tick_ = 0;
  bool line_on_at_tick_ = false;
  Nanos deadline_ = 0;
  Nanos homing_requested_at_ = 0;
  std::uint32_t consecutive_late_ = 0;
  bool have_seq_ = false, finished_ = false, started_ = false;
  std::uint32_t last_seq_ = 0;
  std::uint64_t heartbeats_ = 0;
  std::vector<msg::StripePoint> points_;
  std::array<char, msg::kMaxFaultText> text_{};
  std::atomic<bool> stop_requested_{false};
};

}  // namespace fs::fw
