#include "firmware/loop/controller.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "common/monotonic_time.hpp"

namespace fs::fw {

const char* to_string(State s) {
  switch (s) {
    case State::Idle:
      return "idle";
    case State::Homing:
      return "homing";
    case State::Ready:
      return "ready";
    case State::Scanning:
      return "scanning";
    case State::Done:
      return "done";
    case State::Fault:
      return "fault";
  }
  return "unknown";
}

namespace {
Nanos cpu_now() { return monotonic_ns(); }  // wall-clock stopwatch for extraction time (not the loop clock)
}  // namespace

msg::LoopStats LoopReport::stats() const {
  msg::LoopStats s;
  s.lateness_min_ns = lateness.min();
  s.lateness_median_ns = lateness.quantile(0.5);
  s.lateness_p99_ns = lateness.quantile(0.99);
  s.lateness_p999_ns = lateness.quantile(0.999);
  s.lateness_max_ns = lateness.max();
  s.overruns = overruns;
  s.extraction_mean_ns = extractions ? extract_total_ns / extractions : 0;
  s.extraction_max_ns = extract_max_ns;
  return s;
}

Controller::Controller(Devices dev, const LoopConfig& cfg, Publisher& pub, const ScannerCalibration& cal)
    : dev_(dev), cfg_(cfg), pub_(pub), cal_(cal), points_(std::min(cfg.max_rows, msg::kMaxStripePoints)) {
  if (cfg_.period <= 0) cfg_.period = 500'000;
}

Controller::~Controller() {
  dev_.laser.force_off();
  dev_.galvo.disable();
  dev_.camera.stop();
}

void Controller::start() {
  const Nanos now = dev_.clock.now();
  t0_ = now;
  deadline_ = now;
  started_ = true;
  finished_ = false;
  report_ = LoopReport{};
  prev_tick_ = last_tick_ = now;
  line_on_at_tick_ = false;
  dev_.laser.force_off();
  msg::ScanBegin b;
  b.scan_id = cfg_.scan_id;
  b.scanner_model = "facetscan-sim";
  b.calibration = cal_;
  b.calibration.first_step = cfg_.first_step;
  b.calibration.step_count = cfg_.steps;
  b.pixel_bits = 8;
  b.start_time_ns = now;
  pub_.begin(b);
  dev_.camera.start(now);
  dev_.galvo.enable(now);
  dev_.galvo.start_homing(now);
  homing_requested_at_ = now;
  report_.state = State::Homing;
  state_since_ = now;
  last_frame_at_ = now;
  last_heartbeat_ = now;
}

void Controller::set_laser(bool on, Nanos now) {
  if (on) {
    dev_.laser.set(true, now);
    laser_on_at_ = now;
  } else if (dev_.laser.is_on()) {
    dev_.laser.set(false, now);
    laser_on_at_ = -1;
  }
}

int format_laser_off(char* buf, std::size_t n, const FaultEvent& e, Nanos period) {
  if (e.laser_still_emitting)
    return std::snprintf(buf, n, "laser line still emitting after the off command (period %.2f ms)",
                         static_cast<double>(period) / 1e6);
  if (e.laser_already_off)
    return std::snprintf(buf, n, "laser already off (period %.2f ms)", static_cast<double>(period) / 1e6);
  return std::snprintf(buf, n, "laser off after %.2f ms (period %.2f ms)",
                       static_cast<double>(e.latency_ns) / 1e6, static_cast<double>(period) / 1e6);
}

bool Controller::line_emitting() const {
  bool emitting = false;
  if (dev_.laser.monitor(emitting)) return emitting;
  return dev_.laser.is_on();
}

FaultEvent* Controller::new_event(FaultCode code, Nanos now) {
  ++report_.fault_count;
  if (report_.fault_events_n >= report_.fault_events.size()) return nullptr;
  FaultEvent& e = report_.fault_events[report_.fault_events_n++];
  e = FaultEvent{};
  e.code = code;
  e.time = now;
  e.onset = now;
  e.step = step_;
  e.state = report_.state;
  return &e;
}

void Controller::warn(FaultCode code, Nanos now, const char* detail) {
  new_event(code, now);
  std::snprintf(text_.data(), text_.size(), "%s: %s", to_string(code), detail);
  pub_.fault(static_cast<std::uint32_t>(code), text_.data());
}

void Controller::fault(FaultCode code, Nanos now, Nanos onset) {
  if (report_.state == State::Fault) return;
  // The line's state at the start of this tick (the interlock may have switched it off already) or now.
  const bool was_on = line_on_at_tick_ || line_emitting();
  dev_.laser.set(false, now);
  dev_.laser.force_off();
  laser_on_at_ = -1;
  const Nanos t_off = dev_.clock.now();
  const bool still = line_emitting();
  dev_.galvo.disable();
  dev_.camera.stop();
  report_.fault = code;
  report_.fault_time = now;
  FaultEvent scratch;
  FaultEvent* e = new_event(code, now);
  if (!e) e = &scratch;
  e->onset = onset >= 0 ? std::min(onset, now) : prev_tick_;
  e->laser_still_emitting = still;
  e->laser_already_off = !still && !was_on;
  e->latency_ns = still ? -1 : (was_on ? std::max<Nanos>(0, t_off - e->onset) : 0);
  if (!still) report_.max_laser_off_latency_ns = std::max(report_.max_laser_off_latency_ns, e->latency_ns);
  const int n = std::snprintf(text_.data(), text_.size(), "%s (state %s, step %u): ", to_string(code),
                              to_string(report_.state), step_);
  if (n > 0 && static_cast<std::size_t>(n) < text_.size())
    format_laser_off(text_.data() + n, text_.size() - static_cast<std::size_t>(n), *e, cfg_.period);
  pub_.fault(static_cast<std::uint32_t>(code), text_.data());
  report_.state = State::Fault;
  state_since_ = now;
}

void Controller::record_lateness(Nanos lateness) {
  report_.lateness.add(lateness);
  if (lateness > cfg_.late_limit) {
    ++report_.overruns;
    ++consecutive_late_;
  } else {
    consecutive_late_ = 0;
  }
}

void Controller::account_frame(const FrameView& f, Nanos now) {
  ++report_.frames_captured;
  last_frame_at_ = now;
  if (have_seq_ && f.sequence != last_seq_ + 1) {
    const std::uint32_t gap = f.sequence - last_seq_ - 1;
    report_.frames_dropped += gap;
    char detail[64];
    std::snprintf(detail, sizeof detail, "%u frame(s) before sequence %u", gap, f.sequence);
    warn(FaultCode::FramesDropped, now, detail);
  }
  have_seq_ = true;
  last_seq_ = f.sequence;
}

bool Controller::handle_frame(const FrameView& f, Nanos now) {
  if (laser_on_at_ < 0 || f.timestamp < laser_on_at_) {  // exposed (partly) before the laser came on
    ++report_.frames_stale;
    return false;
  }
  set_laser(false, now);
  const Nanos c0 = cpu_now();
  const ExtractCounts counts = extract_frame(f, cfg_.extract, points_);
  const Nanos dt = cpu_now() - c0;
  report_.extract_total_ns += dt;
  report_.extract_max_ns = std::max(report_.extract_max_ns, dt);
  ++report_.extractions;
  const std::uint32_t candidate_rows = counts.points + counts.saturated + counts.ambiguous;
  if (counts.saturated > 0 && counts.saturated > cfg_.saturated_rows_limit * std::max(1u, candidate_rows)) {
    ++report_.saturated_retries;
    if (retries_ >= cfg_.saturated_retries) {
      fault(FaultCode::FrameSaturated, now);
      return true;
    }
    ++retries_;
    char detail[64];
    std::snprintf(detail, sizeof detail, "frame %u, %u saturated rows", f.sequence, counts.saturated);
    warn(FaultCode::SaturatedRetry, now, detail);
    phase_ = Phase::WaitInPosition;  // laser on again next tick, new exposure
    phase_since_ = now;
    return true;
  }
  msg::Stripe s;
  s.header.scan_id = cfg_.scan_id;
  s.header.step_index = step_;
  s.header.commanded_angle = cal_.laser.mirror_angle(static_cast<double>(cfg_.first_step) + step_);
  const GalvoStatus gs = dev_.galvo.poll(now);
  s.header.measured_position = gs.measured_step;
  s.header.capture_time_ns = f.timestamp;
  s.header.frame_sequence = f.sequence;
  s.header.flags = counts.header_flags();
  s.points = std::span<msg::StripePoint>(points_.data(), counts.points);
  if (pub_.stripe(s))
    ++report_.stripes_sent;
  else
    ++report_.stripes_dropped;
  retries_ = 0;
  ++step_;
  phase_ = Phase::Move;
  phase_since_ = now;
  if (step_ >= cfg_.steps) {
    report_.state = State::Done;
    state_since_ = now;
    dev_.galvo.disable();
    dev_.camera.stop();
  }
  return true;
}

void Controller::tick(Nanos now) {
  ++report_.ticks;
  const State st = report_.state;
  if (st == State::Done || st == State::Fault || st == State::Idle) return;
  prev_tick_ = last_tick_;
  last_tick_ = now;
  line_on_at_tick_ = line_emitting();
  const GalvoStatus gs = dev_.galvo.poll(now);

  // ---- interlock -------------------------------------------------------------------------------------
  const bool host_ok = pub_.host_connected();
  if (!host_ok && host_lost_since_ < 0) host_lost_since_ = now;
  if (host_ok) host_lost_since_ = -1;
  const Nanos laser_on_at = laser_on_at_;  // before the interlock may switch the laser off
  const bool dwell_exceeded = laser_on_at >= 0 && now - laser_on_at > cfg_.max_dwell;
  const bool late = consecutive_late_ > cfg_.max_consecutive_late;
  const bool host_fault =
      cfg_.require_host && host_lost_since_ >= 0 && now - host_lost_since_ >= cfg_.host_grace;
  const bool allowed =
      st == State::Scanning && phase_ == Phase::Expose && gs.in_position && !gs.moving &&
      gs.fault == GalvoFault::None && !dwell_exceeded && !late && !host_fault &&
      std::abs(gs.measured_step - static_cast<double>(cfg_.first_step + static_cast<std::int32_t>(step_))) <=
          0.5;
  if (dev_.laser.is_on() && !allowed) set_laser(false, now);
  bool emitting = false;
  if (dev_.laser.monitor(emitting) && emitting != dev_.laser.is_on())
    return fault(FaultCode::LaserMonitorMismatch, now);
  if (stop_requested_.load(std::memory_order_relaxed)) return fault(FaultCode::Stopped, now);
  if (gs.fault != GalvoFault::None) return fault(fault_code_for(gs.fault), now);
  // The deadline limit was crossed at this tick's deadline + late_limit.
  if (late) return fault(FaultCode::DeadlineMissed, now, deadline_ + cfg_.late_limit);
  if (dwell_exceeded) return fault(FaultCode::DwellOverrun, now, laser_on_at + cfg_.max_dwell);
  if (host_fault) return fault(FaultCode::HostLost, now, host_lost_since_ + cfg_.host_grace);
  if (st == State::Scanning && now - last_frame_at_ > cfg_.camera_timeout)
    return fault(FaultCode::CameraTimeout, now, last_frame_at_ + cfg_.camera_timeout);

  if (now - last_heartbeat_ >= cfg_.heartbeat_period) {
    last_heartbeat_ = now;
    msg::Heartbeat hb;
    hb.time_ns = now;
    hb.counter = heartbeats_++;
    hb.state = static_cast<std::uint8_t>(st);
    pub_.heartbeat(hb);
  }

  // ---- camera: consume whatever is ready (never blocks) --------------------------------------------------
  FrameView f;
  for (int i = 0; i < 8 && report_.state == st; ++i) {
    const GrabResult r = dev_.camera.grab(now, f);
    if (r == GrabResult::Timeout) break;
    if (r == GrabResult::Error) return fault(FaultCode::CameraError, now);
    account_frame(f, now);
    const bool taken = st == State::Scanning && phase_ == Phase::Expose && handle_frame(f, now);
    // Done / Fault stopped the camera inside handle_frame: its buffers are gone with it (a real V4L2 camera
    // refuses the release of a buffer it no longer hands out), so release only while still running.
    if (report_.state != st) break;
    dev_.camera.release(f);
    if (taken) break;
  }
  if (report_.state != st) return;

  // ---- state machine ----------------------------------------------------------------------------------
  switch (st) {
    case State::Homing:
      // Drives that accept homing only once enabled (CiA 402: after the state machine reached Operation
      // Enabled) ignore the first request: repeat it while the galvo is enabled, idle and not homed.
      if (!gs.homed && !gs.moving && gs.enabled && now - homing_requested_at_ >= 50'000'000) {
        dev_.galvo.start_homing(now);
        homing_requested_at_ = now;
      }
      if (gs.homed && !gs.moving) {
        report_.state = State::Ready;
        state_since_ = now;
      } else if (now - state_since_ > cfg_.homing_timeout) {
        fault(FaultCode::HomeNotFound, now, state_since_ + cfg_.homing_timeout);
      }
      break;
    case State::Ready:
      report_.state = State::Scanning;
      state_since_ = now;
      step_ = 0;
      phase_ = Phase::Move;
      last_frame_at_ = now;
      [[fallthrough]];
    case State::Scanning:
      switch (phase_) {
        case Phase::Move:
          set_laser(false, now);
          dev_.galvo.move_to(cfg_.first_step + static_cast<std::int32_t>(step_), now);
          phase_ = Phase::WaitInPosition;
          phase_since_ = now;
          break;
        case Phase::WaitInPosition:
          if (gs.in_position && gs.commanded_step == cfg_.first_step + static_cast<std::int32_t>(step_)) {
            const GalvoStatus again = dev_.galvo.poll(now);
            if (again.in_position) {
              phase_ = Phase::Expose;
              phase_since_ = now;
              set_laser(true, now);
            }
          } else if (now - phase_since_ > cfg_.move_timeout) {
            fault(FaultCode::MoveTimeout, now, phase_since_ + cfg_.move_timeout);
          }
          break;
        case Phase::Expose:
          break;
      }
      break;
    default:
      break;
  }
}

const LoopReport& Controller::run() {
  start();
  loop();
  finish();
  return report_;
}

void Controller::loop() {
  while (run_one()) {
  }
}

bool Controller::run_one() {
  if (report_.state == State::Done || report_.state == State::Fault) return false;
  deadline_ += cfg_.period;
  const bool sleeps = dev_.clock.now() < deadline_;
  dev_.clock.sleep_until(deadline_);
  const Nanos now = dev_.clock.now();
  const Nanos lateness = now - deadline_;
  record_lateness(lateness);
  if (sleeps)
    report_.wakeup.add(lateness);
  else
    ++report_.ticks_without_sleep;
  if (lateness >= cfg_.period) deadline_ += (lateness / cfg_.period) * cfg_.period;  // skip missed periods
  tick(now);
  return report_.state != State::Done && report_.state != State::Fault;
}

void Controller::finish() {
  if (finished_) return;
  finished_ = true;
  const Nanos now = dev_.clock.now();
  // A line that stuck on at the last switch-on is not seen by a later tick (the scan went Done in the tick
  // that switched it off): check the line once more, the scan ends in the fault then.
  bool emitting = false;
  if (report_.state != State::Fault && dev_.laser.monitor(emitting) && emitting) {
    prev_tick_ = last_tick_;
    line_on_at_tick_ = true;
    fault(FaultCode::LaserMonitorMismatch, now);
  }
  dev_.laser.set(false, now);
  dev_.laser.force_off();
  dev_.galvo.disable();
  dev_.camera.stop();
  report_.stripes_dropped = std::max(report_.stripes_dropped, pub_.stripes_dropped());
  report_.frames_dropped = std::max(report_.frames_dropped, dev_.camera.frames_dropped());
  if (report_.stripes_dropped > 0) {
    char detail[64];
    std::snprintf(detail, sizeof detail, "%u stripe(s) lost", report_.stripes_dropped);
    warn(FaultCode::StripesDropped, now, detail);
  }
  msg::ScanEnd e;
  e.scan_id = cfg_.scan_id;
  e.stripes_sent = report_.stripes_sent;
  e.frames_captured = report_.frames_captured;
  e.frames_dropped = report_.frames_dropped;
  e.stripes_dropped = report_.stripes_dropped;
  e.fault_count = report_.fault_count;
  e.last_fault_code = static_cast<std::uint32_t>(report_.fault);
  e.completed = report_.state == State::Done ? 1 : 0;
  e.loop = report_.stats();
  pub_.end(e);
}

}  // namespace fs::fw
