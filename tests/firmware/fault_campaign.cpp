// Fault campaign: the interlock at volume. Runs many short scans of the controller loop on the hw-sim twins
// (virtual time, in process), each with one random fault of a random kind at a random trigger, on every twin:
// the step/dir galvo twin (stall, missed steps, home switch stuck open / closed), the CiA 402 drive twin
// behind the real CAN master (drive fault, stall, no response, heartbeat loss, bus-off), the camera twin
// (timeout, dropped frames, saturated frames), the laser twin (line stuck on), the clock (late wake-ups), the
// host link (lost with require_host) and a too short dwell limit. For every run it checks, against the twins'
// own logs (not the loop's word):
//   - interlock: the laser never emits while a step pulse moves the mirror; whenever it is switched on the
//     mirror stands on an integer step; no emission lasts longer than max_dwell + one period;
//   - a fatal fault ends in Fault with the laser line off from the fault on (for a stuck line: commanded off
//     and the fault raised within one period of the line disagreeing), never switched on again;
//   - the loop's measured laser-off latency is <= one period and agrees with the laser twin's log (the line
//     emitting at the onset and off at onset + latency, or off already at the onset);
//   - a warning (dropped / saturated frames) ends in Done with every step scanned and its Fault message.
// Prints the counts; exit 0 only without a violation.
//   fault_campaign --faults 100000 [--seed 1] [--steps 12] [--verbose]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "firmware/loop/controller.hpp"
#include "hw-sim/scene/prng.hpp"
#include "hw-sim/sim_rig.hpp"
#include "hw-sim/table_renderer.hpp"
#ifdef FACETSCAN_HAVE_BACKENDS
#include "hw-sim/can/cia402_twin.hpp"
#include "hw-sim/can/sim_can_galvo.hpp"
#endif

namespace {

using namespace fs;
using fw::FaultCode;
using fw::Nanos;
using fw::State;

constexpr Nanos kMs = 1'000'000;

// Uniform integer in [lo, hi].
std::int64_t rnd(sim::Prng& r, std::int64_t lo, std::int64_t hi) {
  return lo + static_cast<std::int64_t>(r.below(static_cast<std::uint64_t>(hi - lo + 1)));
}

// In memory, no thread: what the loop published; the host link can be lost after n stripes.
class MemoryPublisher final : public fw::Publisher {
 public:
  void begin(const msg::ScanBegin&) override {}
  bool stripe(const msg::Stripe& s) override {
    steps.push_back(s.header.step_index);
    frames.push_back(s.header.frame_sequence);
    last_capture = s.header.capture_time_ns;
    return true;
  }
  void heartbeat(const msg::Heartbeat&) override {}
  void fault(std::uint32_t code, const char* text) override {
    codes.push_back(code);
    texts.emplace_back(text);
  }
  void end(const msg::ScanEnd& e) override { ends.push_back(e); }
  bool host_connected() const override {
    return lose_after < 0 || static_cast<long>(steps.size()) < lose_after;
  }
  std::uint32_t stripes_dropped() const override { return 0; }
  long lose_after = -1;
  std::vector<std::uint32_t> steps, frames, codes;
  Nanos last_capture = -1;
  std::vector<std::string> texts;
  std::vector<msg::ScanEnd> ends;
};

// The laser as the loop sees it, checking at each switch-on that the mirror stands on an integer step.
class CheckedLaser final : public fw::Laser {
 public:
  CheckedLaser(sim::SimLaser& l, sim::SimMirror& m, double tol) : laser_(l), mirror_(m), tol_(tol) {}
  void set(bool on, Nanos now) override {
    if (on && !laser_.is_on()) {
      const double x = mirror_.position_at(now);
      if (std::abs(x - std::round(x)) > tol_ && moving_on++ == 0) {
        first_t = now;
        first_x = x;
      }
    }
    laser_.set(on, now);
  }
  bool is_on() const override { return laser_.is_on(); }
  void force_off() noexcept override { laser_.force_off(); }
  bool monitor(bool& emitting) const override { return laser_.monitor(emitting); }
  std::uint32_t moving_on = 0;
  Nanos first_t = -1;
  double first_x = 0;

 private:
  sim::SimLaser& laser_;
  sim::SimMirror& mirror_;
  double tol_;
};

enum class Kind {
  GalvoStall,
  GalvoMissedSteps,
  GalvoHomeOpen,
  GalvoHomeClosed,
  CanDriveFault,
  CanStall,
  CanNoResponse,
  CanHeartbeatLoss,
  CanBusOff,
  CameraTimeout,
  CameraDrop,
  CameraSaturate,
  CameraSaturateLong,
  LaserStuck,
  ClockLate,
  HostLost,
  DwellShort,
  kCount
};

const char* name(Kind k) {
  static const char* n[] = {
      "galvo.stall",         "galvo.missed-steps", "galvo.home-stuck", "galvo.home-stuck,level=on",
      "can.drive-fault",     "can.stall",          "can.no-response",  "can.heartbeat-loss",
      "can.bus-off",         "camera.timeout",     "camera.drop",      "camera.saturate",
      "camera.saturate x20", "laser.stuck",        "clock.late",       "link.host-lost",
      "config.dwell-short"};
  return n[static_cast<int>(k)];
}

bool is_can(Kind k) { return k >= Kind::CanDriveFault && k <= Kind::CanBusOff; }
bool is_warning(Kind k) { return k == Kind::CameraDrop || k == Kind::CameraSaturate; }

// The documented end state of each kind (docs/firmware.md, "Faults"): the fatal codes it may end in.
bool expected_code(Kind k, FaultCode c) {
  switch (k) {
    case Kind::GalvoStall:
    case Kind::GalvoMissedSteps:  // a missed step on a one-step move reads as a stall
      return c == FaultCode::GalvoStall || c == FaultCode::GalvoMissedSteps;
    case Kind::GalvoHomeOpen:
    case Kind::GalvoHomeClosed:
      return c == FaultCode::HomeNotFound;
    case Kind::CanDriveFault:
      return c == FaultCode::GalvoDrive;
    case Kind::CanStall:  // following error
      return c == FaultCode::GalvoStall || c == FaultCode::MoveTimeout;
    case Kind::CanNoResponse:
    case Kind::CanHeartbeatLoss:
      return c == FaultCode::GalvoCommLost || c == FaultCode::MoveTimeout;
    case Kind::CanBusOff:
      return c == FaultCode::GalvoBusOff || c == FaultCode::GalvoCommLost || c == FaultCode::MoveTimeout;
    case Kind::CameraTimeout:
      return c == FaultCode::CameraTimeout;
    case Kind::CameraSaturateLong:
      return c == FaultCode::FrameSaturated;
    case Kind::LaserStuck:
      return c == FaultCode::LaserMonitorMismatch;
    case Kind::ClockLate:
      return c == FaultCode::DeadlineMissed;
    case Kind::HostLost:
      return c == FaultCode::HostLost;
    case Kind::DwellShort:
      return c == FaultCode::DwellOverrun;
    default:
      return false;
  }
}

struct Totals {
  std::uint64_t runs = 0, injected = 0, not_triggered = 0, fatal = 0, warnings = 0;
  std::uint64_t off_within_period = 0, already_off = 0, stuck_commanded_off = 0, violations = 0,
                late_done = 0;
  Nanos max_latency = 0;
  std::map<std::string, std::uint64_t> per_kind;
  std::map<std::string, std::uint64_t> per_code;
};

struct Options {
  std::uint64_t faults = 2000;
  std::uint64_t seed = 1;
  std::uint32_t steps = 12;
  bool verbose = false;
};

ScannerCalibration tiny_calibration(std::uint32_t steps) {
  ScannerCalibration c = ScannerCalibration::bench_default(steps);
  c.camera.width = 96;
  c.camera.height = 64;
  c.camera.fx = c.camera.fy = 120.0;
  c.camera.cx = 47.5;
  c.camera.cy = 31.5;
  return c;
}

class Campaign {
 public:
  explicit Campaign(const Options& o) : o_(o), cal_(tiny_calibration(o.steps)), renderer_(cal_) {}

  // One scan with one fault; returns false when it violated a rule (reason printed).
  void run_one(std::uint64_t index, sim::Prng& rng, Totals& t) {
    Kind kind;
    do {
      kind = static_cast<Kind>(rnd(rng, 0, static_cast<int>(Kind::kCount) - 1));
#ifndef FACETSCAN_HAVE_BACKENDS
    } while (is_can(kind));
#else
    } while (false);
#endif
    const bool can =
        is_can(kind) || (kind >= Kind::CameraTimeout && kind != Kind::HostLost && rng.uniform() < 0.3);
    const Nanos period = 500'000;
    fw::LoopConfig cfg;
    cfg.steps = o_.steps;
    cfg.max_rows = cal_.camera.height;
    cfg.period = period;
    sim::RigConfig rc;
    const std::int64_t steps = o_.steps;
    char spec[96] = "";
    char spec_text[96] = "";
    // Triggers inside the scan: steps 1..steps-1, the scan's frames, its laser switch-ons, its time span.
    const Nanos scan_ms = 40 + 10 * steps;
    switch (kind) {
      case Kind::GalvoStall:
        std::snprintf(spec, sizeof spec, "galvo.stall@step=%ld", static_cast<long>(rnd(rng, 1, steps - 1)));
        break;
      case Kind::GalvoMissedSteps:
        std::snprintf(spec, sizeof spec, "galvo.missed-steps@step=%ld,count=%ld",
                      static_cast<long>(rnd(rng, 1, steps - 1)), static_cast<long>(rnd(rng, 1, 4)));
        break;
      case Kind::GalvoHomeOpen:
        std::snprintf(spec, sizeof spec, "galvo.home-stuck");
        break;
      case Kind::GalvoHomeClosed:
        std::snprintf(spec, sizeof spec, "galvo.home-stuck,level=on");
        break;
      case Kind::CameraTimeout:
        std::snprintf(spec, sizeof spec, "camera.timeout@t=%.4f", rng.uniform() * scan_ms * 1e-3);
        break;
      case Kind::CameraDrop:
        std::snprintf(spec, sizeof spec, "camera.drop@frame=%ld,count=%ld",
                      static_cast<long>(rnd(rng, 2, 2 * steps)), static_cast<long>(rnd(rng, 1, 3)));
        break;
      case Kind::CameraSaturate:
        std::snprintf(spec, sizeof spec, "camera.saturate@frame=%ld,count=%ld",
                      static_cast<long>(rnd(rng, 2, 2 * steps)), static_cast<long>(rnd(rng, 1, 2)));
        break;
      case Kind::CameraSaturateLong:
        std::snprintf(spec, sizeof spec, "camera.saturate@frame=%ld,count=40",
                      static_cast<long>(rnd(rng, 2, 2 * steps)));
        break;
      case Kind::LaserStuck:
        std::snprintf(spec, sizeof spec, "laser.stuck@on=%ld", static_cast<long>(rnd(rng, 0, steps - 1)));
        break;
      case Kind::DwellShort:
        cfg.max_dwell = static_cast<Nanos>(rnd(rng, 1, 5)) * kMs + rnd(rng, 0, 999) * 1000;
        break;
      case Kind::HostLost:
        cfg.require_host = true;
        cfg.host_grace = static_cast<Nanos>(rnd(rng, 0, 4)) * period / 2;
        break;
      default:
        break;
    }
    if (spec[0]) rc.faults.push_back(spec);
    sim::SimRig rig(renderer_, rc);
    MemoryPublisher pub;
    if (kind == Kind::HostLost) pub.lose_after = rnd(rng, 0, steps - 1);
    const Nanos t0 = rig.clock.now();
    Nanos late_from = -1;
    if (kind == Kind::ClockLate) {
      late_from = t0 + rnd(rng, 1, static_cast<int>(scan_ms)) * kMs + rnd(rng, 0, 499) * 1000;
      const Nanos delay = cfg.late_limit + rnd(rng, 1, 200) * 1000;
      rig.clock.inject_lateness(late_from, t0 + 100'000 * kMs, delay);
      std::snprintf(spec_text, sizeof spec_text, "late from %.3f ms by %.3f ms", (late_from - t0) / 1e6,
                    delay / 1e6);
    }
    bool can_fired = false;
    Nanos can_at = -1;
#ifdef FACETSCAN_HAVE_BACKENDS
    sim::SimCanBackend b;
    if (can) {
      b = sim::make_sim_can_galvo("sim-can", rig.clock);
      sim::SimMirror* m = &rig.mirror;
      b.twin->set_position_callback([m](double pos, std::int64_t tt) { m->command(tt, pos); });
      if (is_can(kind)) {
        can_at = t0 + rnd(rng, 1, static_cast<int>(scan_ms + 60)) * kMs;
        const Kind k = kind;
        b.twin->schedule(can_at, [k, &can_fired](sim::Cia402Twin& tw) {
          can_fired = true;
          switch (k) {
            case Kind::CanDriveFault:
              tw.inject_drive_fault(0x2310);
              break;
            case Kind::CanStall:
              tw.set_stall(true);
              break;
            case Kind::CanNoResponse:
              tw.set_no_response(true);
              break;
            case Kind::CanHeartbeatLoss:
              tw.set_heartbeat_loss(true);
              break;
            default:
              tw.inject_bus_off(400 * kMs);
              break;
          }
        });
      }
    }
    fw::Galvo& galvo = can ? *b.galvo : static_cast<fw::Galvo&>(rig.galvo);
#else
    fw::Galvo& galvo = rig.galvo;
#endif
    CheckedLaser laser(rig.laser, rig.mirror, can ? 0.05 : 0.02);
    fw::Controller ctl(fw::Devices{rig.clock, galvo, laser, rig.camera}, cfg, pub, cal_);
    ctl.start();
    ctl.loop();
    // The twin's line right after the tick that ended the scan, before finish() forces everything off.
    const bool emitting_after_loop = rig.laser.emitting(), commanded_after_loop = rig.laser.is_on();
    ctl.finish();
    const fw::LoopReport& r = ctl.report();

    // ---- did the fault take effect? ------------------------------------------------------------------
    bool fired = false;
    Nanos fired_at = -1;
    if (spec[0]) {
      fired_at = rig.faults.fired_at(0);
      fired = fired_at >= 0;
    } else if (is_can(kind)) {
      fired = can_fired;
      fired_at = can_at;
    } else if (kind == Kind::ClockLate) {
      fired = r.lateness.max() > 0;
      fired_at = late_from;
    } else if (kind == Kind::HostLost)
      fired = !pub.host_connected();
    else if (kind == Kind::DwellShort)
      fired = r.fault == FaultCode::DwellOverrun;  // a dwell limit longer than every exposure never bites
    ++t.runs;
    if (!fired) {
      ++t.not_triggered;
      return;
    }
    ++t.injected;
    ++t.per_kind[std::string(name(kind)) + (can && !is_can(kind) ? " (sim-can)" : "")];

    std::vector<std::string> why;
    auto fail = [&](std::string s) { why.push_back(std::move(s)); };
    const auto& log = rig.laser.log();
    if (rig.laser.log_overflow()) fail("laser log overflow");
    // Interlock, from the twins' logs.
    if (laser.moving_on) {
      char b[160];
      std::snprintf(b, sizeof b,
                    "laser switched on while the mirror was between steps (t %.3f ms, mirror at %.4f)",
                    (laser.first_t - t0) / 1e6, laser.first_x);
      fail(b);
    }
    if (!can)
      for (const auto& e : rig.lines.step_log())
        if (e.direction != 0 && rig.laser.emitting_at(e.t) &&
            !(kind == Kind::LaserStuck && r.state == State::Fault && e.t >= r.fault_time))
          fail("laser emitting during a step pulse");
    Nanos on_since = -1;
    for (const auto& e : log) {
      const bool on = e.emitting && !(kind == Kind::LaserStuck && !e.commanded);
      if (on && on_since < 0) on_since = e.t;
      if (!on && on_since >= 0) {
        if (e.t - on_since > cfg.max_dwell + period) fail("emission longer than max_dwell + one period");
        on_since = -1;
      }
    }
    if (rig.laser.is_on()) fail("laser commanded on at the end");

    if (r.state == State::Fault) {
      ++t.fatal;
      ++t.per_code[fw::to_string(r.fault)];
      if (is_warning(kind)) fail(std::string("warning kind ended in fault ") + fw::to_string(r.fault));
      if (!is_warning(kind) && !expected_code(kind, r.fault))
        fail(std::string("undocumented end state: ") + fw::to_string(r.fault));
      // The loop's own record of it.
      const fw::FaultEvent* fe = nullptr;
      for (std::uint32_t i = 0; i < r.fault_events_n; ++i)
        if (fw::is_fatal(r.fault_events[i].code)) fe = &r.fault_events[i];
      if (!fe) {
        fail("no fault event");
      } else {
        if (commanded_after_loop) fail("laser commanded on after the fault tick");
        for (const auto& e : log)
          if (e.t > r.fault_time && e.commanded) fail("laser commanded on after the fault");
        if (kind == Kind::LaserStuck) {
          // The line itself stays on (that is the fault): commanded off, and the fault raised within one
          // period of the line first disagreeing with the command.
          Nanos stuck_at = -1;
          for (const auto& e : log)
            if (!e.commanded && e.emitting) {
              stuck_at = e.t;
              break;
            }
          if (!fe->laser_still_emitting) fail("stuck line not reported as still emitting");
          if (stuck_at < 0 || r.fault_time - stuck_at > period)
            fail("stuck line not detected within one period");
          else
            ++t.stuck_commanded_off;
        } else {
          if (emitting_after_loop || rig.laser.emitting_at(r.fault_time))
            fail("laser emitting after the fault");
          if (fe->laser_still_emitting) fail("loop reports the line still emitting");
          if (fe->laser_already_off) {
            if (rig.laser.emitting_at(fe->onset))
              fail("loop says already off, the twin emitted at the onset");
            ++t.already_off;
            ++t.off_within_period;
          } else {
            const Nanos lat = fe->latency_ns;
            if (lat > period) fail("laser-off latency " + std::to_string(lat) + " ns > one period");
            if (!rig.laser.emitting_at(fe->onset))
              fail("loop measured a latency, the twin was off at the onset");
            if (rig.laser.emitting_at(fe->onset + lat)) fail("twin still emitting at onset + latency");
            if (rig.laser.emitting_at(fe->onset + period)) fail("twin emitting one period after the onset");
            if (lat <= period && !rig.laser.emitting_at(fe->onset + lat)) ++t.off_within_period;
            t.max_latency = std::max(t.max_latency, lat);
          }
          // The Fault message carries the measurement.
          bool text = false;
          for (std::size_t i = 0; i < pub.codes.size(); ++i)
            if (pub.codes[i] == static_cast<std::uint32_t>(r.fault))
              text = text ||
                     pub.texts[i].find(fe->laser_already_off ? "laser already off" : "laser off after") !=
                         std::string::npos;
          if (!text) fail("Fault message without the laser-off latency");
        }
      }
    } else if (r.state == State::Done) {
      if (pub.steps.size() != static_cast<std::size_t>(steps)) fail("a step is missing in a completed scan");
      for (const std::uint32_t seq : pub.frames) {
        const sim::FrameRecord* fr = rig.camera.find(seq);
        if (!fr || fr->saturated) fail("a stripe from a saturated or unknown frame");
      }
      if (rig.laser.emitting()) fail("laser emitting at the end");
      if (is_warning(kind)) {
        ++t.warnings;
        ++t.per_code["done (warning)"];
        if (kind == Kind::CameraDrop &&
            std::find(pub.codes.begin(), pub.codes.end(),
                      static_cast<std::uint32_t>(FaultCode::FramesDropped)) == pub.codes.end())
          fail("no frames-dropped warning");
      } else {
        // A fatal kind may fire too late to be detected before the scan completes: only within its
        // detection window before the last stripe's exposure (heartbeat consumer time for the CAN link, the
        // consecutive late wake-ups for the clock, the camera timeout, a few periods for what the next poll
        // sees). Otherwise it must have ended in Fault.
        Nanos window = 4 * period;
        if (kind == Kind::CanHeartbeatLoss || kind == Kind::CanNoResponse || kind == Kind::CanBusOff)
          window = 300 * kMs;
        else if (kind == Kind::CanStall)
          window = cfg.move_timeout + 4 * period;
        else if (kind == Kind::ClockLate)
          window = static_cast<Nanos>(cfg.max_consecutive_late + 2) * (period + cfg.late_limit + 200'000);
        else if (kind == Kind::CameraTimeout)
          window = cfg.camera_timeout + 4 * period;
        if (fired_at < 0 || fired_at < pub.last_capture - window)
          fail("fatal fault kind ended in Done (fired " +
               std::to_string((pub.last_capture - fired_at) / 1000) + " us before the last exposure)");
        ++t.late_done;
        ++t.per_code["done (fault after the last step)"];
      }
    } else {
      fail(std::string("ended in state ") + fw::to_string(r.state));
    }
    if (!why.empty()) {
      ++t.violations;
      std::fprintf(stderr, "VIOLATION run %llu (%s%s%s%s%s%s): %s\n", static_cast<unsigned long long>(index),
                   name(kind), can && !is_can(kind) ? " (sim-can)" : "", spec[0] ? " " : "", spec,
                   spec_text[0] ? " " : "", spec_text, why.front().c_str());
    } else if (o_.verbose) {
      std::fprintf(stderr, "run %llu %s %s: %s\n", static_cast<unsigned long long>(index), name(kind), spec,
                   r.state == State::Fault ? fw::to_string(r.fault) : "done");
    }
  }

 private:
  Options o_;
  ScannerCalibration cal_;
  sim::TableStripeRenderer renderer_;
};

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::uint64_t {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "fault_campaign: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return std::strtoull(argv[++i], nullptr, 10);
    };
    if (a == "--faults")
      o.faults = value();
    else if (a == "--seed")
      o.seed = value();
    else if (a == "--steps")
      o.steps = static_cast<std::uint32_t>(std::max<std::uint64_t>(4, value()));
    else if (a == "--verbose")
      o.verbose = true;
    else {
      std::fprintf(stderr, "usage: fault_campaign [--faults N] [--seed S] [--steps N] [--verbose]\n");
      return 2;
    }
  }
  Campaign c(o);
  sim::Prng rng(o.seed);
  Totals t;
  const auto start = std::chrono::steady_clock::now();
  for (std::uint64_t i = 0; t.injected < o.faults; ++i) {
    c.run_one(i, rng, t);
    if (t.runs > 4 * o.faults + 100) {
      std::fprintf(stderr, "fault_campaign: too many faults did not trigger\n");
      return 1;
    }
  }
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf(
      "fault campaign (seed %llu, %u steps a scan, period 0.5 ms): %llu faults injected in %llu scans "
      "(%llu did not trigger) in %.1f s\n",
      static_cast<unsigned long long>(o.seed), o.steps, static_cast<unsigned long long>(t.injected),
      static_cast<unsigned long long>(t.runs), static_cast<unsigned long long>(t.not_triggered), secs);
  std::printf("  per kind:");
  for (const auto& [k, n] : t.per_kind)
    std::printf(" %s %llu,", k.c_str(), static_cast<unsigned long long>(n));
  std::printf("\n  end states:");
  for (const auto& [k, n] : t.per_code)
    std::printf(" %s %llu,", k.c_str(), static_cast<unsigned long long>(n));
  std::printf(
      "\n  fatal %llu: laser off within one period %llu (of which already off at the onset %llu, max "
      "latency %.3f ms), stuck line commanded off + fault within one period %llu\n"
      "  warnings %llu: scan completed, every step, interlock clean\n"
      "  fatal kinds fired within their detection window before the last exposure (scan completed, laser "
      "off, "
      "interlock clean): %llu\n"
      "  violations: %llu\n",
      static_cast<unsigned long long>(t.fatal), static_cast<unsigned long long>(t.off_within_period),
      static_cast<unsigned long long>(t.already_off), t.max_latency / 1e6,
      static_cast<unsigned long long>(t.stuck_commanded_off), static_cast<unsigned long long>(t.warnings),
      static_cast<unsigned long long>(t.late_done), static_cast<unsigned long long>(t.violations));
  return t.violations == 0 ? 0 : 1;
}
