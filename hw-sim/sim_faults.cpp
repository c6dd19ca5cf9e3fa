#include "hw-sim/sim_faults.hpp"

#include <charconv>
#include <cmath>

#include <fmt/core.h>

#include "common/error.hpp"

namespace fs::sim {

const char* to_string(FaultKind k) {
  switch (k) {
    case FaultKind::GalvoMissedSteps:
      return "galvo.missed-steps";
    case FaultKind::GalvoStall:
      return "galvo.stall";
    case FaultKind::GalvoHomeStuck:
      return "galvo.home-stuck";
    case FaultKind::CameraTimeout:
      return "camera.timeout";
    case FaultKind::CameraDrop:
      return "camera.drop";
    case FaultKind::CameraSaturate:
      return "camera.saturate";
    case FaultKind::LaserStuck:
      return "laser.stuck";
  }
  return "unknown";
}

namespace {

[[noreturn]] void bad(std::string_view spec, const std::string& what) {
  throw Error(fmt::format("fault spec '{}': {}", spec, what));
}

std::int64_t parse_int(std::string_view spec, std::string_view key, std::string_view v,
                       bool allow_negative = false) {
  std::int64_t x = 0;
  const auto [p, ec] = std::from_chars(v.data(), v.data() + v.size(), x);
  if (ec != std::errc() || p != v.data() + v.size() || (x < 0 && !allow_negative))
    bad(spec,
        fmt::format("'{}' needs {} integer, got '{}'", key, allow_negative ? "an" : "a non-negative", v));
  return x;
}

fw::Nanos parse_seconds(std::string_view spec, std::string_view key, std::string_view v) {
  // std::from_chars for double is available in GCC 11+.
  double s = 0.0;
  const auto [p, ec] = std::from_chars(v.data(), v.data() + v.size(), s);
  if (ec != std::errc() || p != v.data() + v.size() || !std::isfinite(s) || s < 0.0 || s > 1e6)
    bad(spec, fmt::format("'{}' needs seconds in [0, 1e6], got '{}'", key, v));
  return static_cast<fw::Nanos>(std::llround(s * 1e9));
}

}  // namespace

FaultSpec parse_fault_spec(std::string_view spec) {
  FaultSpec f;
  f.text = std::string(spec);
  std::string_view rest = spec;
  const std::size_t comma = rest.find(',');
  std::string_view head = rest.substr(0, comma);
  rest = comma == std::string_view::npos ? std::string_view() : rest.substr(comma + 1);
  const std::size_t atpos = head.find('@');
  const std::string_view name = head.substr(0, atpos);
  if (name == "galvo.missed-steps")
    f.kind = FaultKind::GalvoMissedSteps;
  else if (name == "galvo.stall")
    f.kind = FaultKind::GalvoStall;
  else if (name == "galvo.home-stuck")
    f.kind = FaultKind::GalvoHomeStuck;
  else if (name == "camera.timeout")
    f.kind = FaultKind::CameraTimeout;
  else if (name == "camera.drop")
    f.kind = FaultKind::CameraDrop;
  else if (name == "camera.saturate")
    f.kind = FaultKind::CameraSaturate;
  else if (name == "laser.stuck")
    f.kind = FaultKind::LaserStuck;
  else
    bad(spec,
        fmt::format("unknown fault '{}' (galvo.missed-steps|stall|home-stuck, camera.timeout|drop|saturate, "
                    "laser.stuck)",
                    name));
  f.level = f.kind == FaultKind::LaserStuck;
  if (atpos != std::string_view::npos) {
    const std::string_view trig = head.substr(atpos + 1);
    const std::size_t eq = trig.find('=');
    if (eq == std::string_view::npos) bad(spec, fmt::format("trigger '{}' needs KEY=VALUE", trig));
    const std::string_view k = trig.substr(0, eq), v = trig.substr(eq + 1);
    if (k == "t") {
      f.trigger = FaultTrigger::Time;
      f.at = parse_seconds(spec, k, v);
    } else if (k == "step" || k == "frame" || k == "on") {
      const bool ok =
          (k == "step" && f.kind <= FaultKind::GalvoHomeStuck) ||
          (k == "frame" && f.kind >= FaultKind::CameraTimeout && f.kind <= FaultKind::CameraSaturate) ||
          (k == "on" && f.kind == FaultKind::LaserStuck);
      if (!ok) bad(spec, fmt::format("trigger '{}' does not apply to {}", k, name));
      f.trigger = k == "step"    ? FaultTrigger::Step
                  : k == "frame" ? FaultTrigger::Frame
                                 : FaultTrigger::LaserOn;
      f.at = parse_int(spec, k, v, k == "step");
    } else {
      bad(spec, fmt::format("unknown trigger '{}' (t, step, frame, on)", k));
    }
  }
  while (!rest.empty()) {
    const std::size_t c = rest.find(',');
    const std::string_view kv = rest.substr(0, c);
    rest = c == std::string_view::npos ? std::string_view() : rest.substr(c + 1);
    const std::size_t eq = kv.find('=');
    if (eq == std::string_view::npos) bad(spec, fmt::format("option '{}' needs KEY=VALUE", kv));
    const std::string_view k = kv.substr(0, eq), v = kv.substr(eq + 1);
    if (k == "count") {
      f.count = parse_int(spec, k, v);
    } else if (k == "for") {
      f.duration = parse_seconds(spec, k, v);
    } else if (k == "level") {
      if (v == "on")
        f.level = true;
      else if (v == "off")
        f.level = false;
      else
        bad(spec, fmt::format("'level' must be on or off, got '{}'", v));
    } else {
      bad(spec, fmt::format("unknown option '{}' (count, for, level)", k));
    }
  }
  if (f.count < 0) f.count = f.kind == FaultKind::GalvoMissedSteps ? 3 : 1;
  return f;
}

void FaultScript::add(FaultSpec spec) {
  specs_.push_back(std::move(spec));
  state_.emplace_back();
}

bool FaultScript::active(std::size_t i, fw::Nanos now, std::int64_t index) {
  const FaultSpec& f = specs_[i];
  State& s = state_[i];
  if (!s.armed) {
    bool go = false;
    switch (f.trigger) {
      case FaultTrigger::Always:
        go = true;
        break;
      case FaultTrigger::Time:
        go = now - t0_ >= f.at;
        break;
      case FaultTrigger::Step:
        go = index == f.at;
        break;
      case FaultTrigger::Frame:
      case FaultTrigger::LaserOn:
        go = index >= f.at;
        break;
    }
    if (!go) return false;
    s.armed = true;
    s.armed_at = now;
  }
  if (f.duration >= 0 && now - s.armed_at >= f.duration) return false;
  return true;
}

namespace {
inline void mark(fw::Nanos& fired, fw::Nanos now) {
  if (fired < 0) fired = now;
}
}  // namespace

bool FaultScript::galvo_pulse_lost(fw::Nanos now, std::int64_t target) {
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    if (specs_[i].kind != FaultKind::GalvoMissedSteps || !active(i, now, target)) continue;
    if (state_[i].used >= specs_[i].count) continue;
    ++state_[i].used;
    mark(state_[i].fired_at, now);
    return true;
  }
  return false;
}

bool FaultScript::galvo_stalled(fw::Nanos now, std::int64_t target) {
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    if (specs_[i].kind != FaultKind::GalvoStall || !active(i, now, target)) continue;
    mark(state_[i].fired_at, now);
    return true;
  }
  return false;
}

bool FaultScript::home_stuck(fw::Nanos now, std::int64_t target, bool& level) {
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    if (specs_[i].kind != FaultKind::GalvoHomeStuck || !active(i, now, target)) continue;
    mark(state_[i].fired_at, now);
    level = specs_[i].level;
    return true;
  }
  return false;
}

bool FaultScript::camera_timeout(fw::Nanos t, std::uint32_t sequence) {
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    if (specs_[i].kind != FaultKind::CameraTimeout || !active(i, t, sequence)) continue;
    mark(state_[i].fired_at, t);
    return true;
  }
  return false;
}

bool FaultScript::camera_drop(fw::Nanos t, std::uint32_t sequence) {
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    if (specs_[i].kind != FaultKind::CameraDrop || !active(i, t, sequence)) continue;
    if (state_[i].used >= specs_[i].count) continue;
    ++state_[i].used;
    mark(state_[i].fired_at, t);
    return true;
  }
  return false;
}

bool FaultScript::camera_saturate(fw::Nanos t, std::uint32_t sequence) {
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    if (specs_[i].kind != FaultKind::CameraSaturate || !active(i, t, sequence)) continue;
    if (state_[i].used >= specs_[i].count) continue;
    ++state_[i].used;
    mark(state_[i].fired_at, t);
    return true;
  }
  return false;
}

bool FaultScript::laser_stuck(fw::Nanos now, std::int64_t switch_on_index, bool& level) {
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    if (specs_[i].kind != FaultKind::LaserStuck || !active(i, now, switch_on_index)) continue;
    mark(state_[i].fired_at, now);
    level = specs_[i].level;
    return true;
  }
  return false;
}

}  // namespace fs::sim
