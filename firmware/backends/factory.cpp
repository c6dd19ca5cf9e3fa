#include "firmware/backends/factory.hpp"

#include <charconv>
#include <limits>
#include <vector>

#include "common/error.hpp"
#include "firmware/backends/gpiod_lines.hpp"
#include "firmware/backends/v4l2_camera.hpp"
#include "firmware/galvo/can_galvo.hpp"

namespace fs::fw {
namespace {

struct KeyValue {
  std::string_view key, value;
};

[[noreturn]] void bad(std::string_view spec, const std::string& what) {
  throw Error("device spec '" + std::string(spec) + "': " + what);
}

std::vector<KeyValue> split_kv(std::string_view spec, std::string_view list) {
  std::vector<KeyValue> kv;
  while (!list.empty()) {
    const auto comma = list.find(',');
    std::string_view item = list.substr(0, comma);
    list = comma == std::string_view::npos ? std::string_view{} : list.substr(comma + 1);
    if (item.empty()) bad(spec, "empty item in the key=value list");
    const auto eq = item.find('=');
    if (eq == std::string_view::npos || eq == 0 || eq + 1 == item.size())
      bad(spec, "expected key=value, got '" + std::string(item) + "'");
    for (const auto& prev : kv)
      if (prev.key == item.substr(0, eq)) bad(spec, "key '" + std::string(prev.key) + "' given twice");
    kv.push_back({item.substr(0, eq), item.substr(eq + 1)});
  }
  return kv;
}

template <typename T>
T number(std::string_view spec, const KeyValue& kv, long long lo, long long hi) {
  long long v = 0;
  auto [p, ec] = std::from_chars(kv.value.data(), kv.value.data() + kv.value.size(), v);
  if (ec != std::errc() || p != kv.value.data() + kv.value.size())
    bad(spec, std::string(kv.key) + "='" + std::string(kv.value) + "' is not an integer");
  if (v < lo || v > hi)
    bad(spec, std::string(kv.key) + "=" + std::to_string(v) + " out of range " + std::to_string(lo) + ".." +
                  std::to_string(hi));
  return static_cast<T>(v);
}

bool flag(std::string_view spec, const KeyValue& kv) {
  if (kv.value == "1" || kv.value == "true" || kv.value == "yes") return true;
  if (kv.value == "0" || kv.value == "false" || kv.value == "no") return false;
  bad(spec, std::string(kv.key) + "='" + std::string(kv.value) + "' is not a boolean (0/1)");
}

GpioLineRef line_ref(std::string_view spec, const KeyValue& kv) {
  GpioLineRef r;
  const bool digits = kv.value.find_first_not_of("0123456789") == std::string_view::npos;
  if (digits)
    r.offset = number<int>(spec, kv, 0, 4095);
  else
    r.name = std::string(kv.value);
  return r;
}

// "prefix:a:b" -> parts after the prefix, split at ':' (at most `max` parts).
std::vector<std::string_view> split_colon(std::string_view spec, std::string_view rest, std::size_t max) {
  std::vector<std::string_view> parts;
  while (true) {
    const auto c = rest.find(':');
    if (c == std::string_view::npos || parts.size() + 1 == max) {
      parts.push_back(rest);
      break;
    }
    parts.push_back(rest.substr(0, c));
    rest = rest.substr(c + 1);
  }
  for (auto p : parts)
    if (p.empty()) bad(spec, "empty field between ':'");
  return parts;
}

}  // namespace

GpioSpec parse_gpio_spec(std::string_view spec) {
  if (spec.substr(0, 5) != "gpio:") bad(spec, "a GPIO galvo spec starts with 'gpio:'");
  auto parts = split_colon(spec, spec.substr(5), 2);
  if (parts.size() != 2) bad(spec, "expected gpio:CHIP:step=L,dir=L,en=L,home=L[,laser=L]");
  GpioSpec g;
  g.chip = std::string(parts[0]);
  for (const auto& kv : split_kv(spec, parts[1])) {
    if (kv.key == "step")
      g.step = line_ref(spec, kv);
    else if (kv.key == "dir")
      g.dir = line_ref(spec, kv);
    else if (kv.key == "en")
      g.enable = line_ref(spec, kv);
    else if (kv.key == "home")
      g.home = line_ref(spec, kv);
    else if (kv.key == "laser")
      g.laser = line_ref(spec, kv);
    else if (kv.key == "home_active_low")
      g.home_active_low = flag(spec, kv);
    else if (kv.key == "en_active_low")
      g.enable_active_low = flag(spec, kv);
    else
      bad(spec, "unknown key '" + std::string(kv.key) +
                    "' (known: step, dir, en, home, laser, home_active_low, en_active_low)");
  }
  const std::pair<const char*, const GpioLineRef*> required[] = {
      {"step", &g.step}, {"dir", &g.dir}, {"en", &g.enable}, {"home", &g.home}};
  for (const auto& [name, ref] : required)
    if (!ref->valid()) bad(spec, std::string("missing line '") + name + "='");
  const GpioLineRef* all[] = {&g.step, &g.dir, &g.enable, &g.home, &g.laser};
  for (int i = 0; i < 5; ++i)
    for (int j = i + 1; j < 5; ++j)
      if (all[i]->valid() && all[j]->valid() && all[i]->offset == all[j]->offset &&
          all[i]->name == all[j]->name)
        bad(spec, "the same line is used twice");
  return g;
}

CanSpec parse_can_spec(std::string_view spec) {
  CanSpec c;
  std::string_view kvs;
  if (spec.substr(0, 4) == "can:") {
    auto parts = split_colon(spec, spec.substr(4), 2);
    c.iface = std::string(parts[0]);
    if (c.iface.size() >= 16) bad(spec, "interface name '" + c.iface + "' longer than 15 characters");
    if (parts.size() == 2) kvs = parts[1];
  } else if (spec == "sim-can") {
  } else if (spec.substr(0, 8) == "sim-can:") {
    kvs = spec.substr(8);
    if (kvs.empty()) bad(spec, "empty key=value list after 'sim-can:'");
  } else {
    bad(spec, "a CAN galvo spec is can:IFACE[:node=N,...] or sim-can[:node=N,...]");
  }
  for (const auto& kv : split_kv(spec, kvs)) {
    if (kv.key == "node")
      c.node = number<std::uint8_t>(spec, kv, 1, 127);
    else if (kv.key == "hb")
      c.heartbeat_ms = number<std::uint16_t>(spec, kv, 10, 10000);
    else if (kv.key == "vel")
      c.velocity = number<std::uint32_t>(spec, kv, 1, 100'000'000);
    else if (kv.key == "acc")
      c.acceleration = number<std::uint32_t>(spec, kv, 1, 1'000'000'000);
    else if (kv.key == "sdo_ms")
      c.sdo_timeout_ms = number<std::uint32_t>(spec, kv, 1, 60000);
    else if (kv.key == "state_ms")
      c.state_timeout_ms = number<std::uint32_t>(spec, kv, 1, 600000);
    else
      bad(spec, "unknown key '" + std::string(kv.key) + "' (known: node, hb, vel, acc, sdo_ms, state_ms)");
  }
  return c;
}

V4l2Spec parse_v4l2_spec(std::string_view spec) {
  if (spec.substr(0, 5) != "v4l2:") bad(spec, "a V4L2 camera spec starts with 'v4l2:'");
  auto parts = split_colon(spec, spec.substr(5), 2);
  V4l2Spec v;
  v.device = std::string(parts[0]);
  if (parts.size() == 2) {
    for (const auto& kv : split_kv(spec, parts[1])) {
      if (kv.key == "fmt") {
        if (kv.value == "GREY")
          v.format = V4l2Fourcc::Grey;
        else if (kv.value == "Y16")
          v.format = V4l2Fourcc::Y16;
        else if (kv.value == "YUYV")
          v.format = V4l2Fourcc::Yuyv;
        else
          bad(spec, "fmt='" + std::string(kv.value) + "' (known: GREY, Y16, YUYV)");
      } else if (kv.key == "width")
        v.width = number<std::uint32_t>(spec, kv, 16, 16384);
      else if (kv.key == "height")
        v.height = number<std::uint32_t>(spec, kv, 16, 16384);
      else if (kv.key == "fps")
        v.fps = number<std::uint32_t>(spec, kv, 1, 10000);
      else if (kv.key == "exposure")
        v.exposure = number<std::int32_t>(spec, kv, 0, std::numeric_limits<std::int32_t>::max());
      else if (kv.key == "buffers")
        v.buffers = number<std::uint32_t>(spec, kv, 4, V4l2Camera::kMaxBuffers);
      else
        bad(spec,
            "unknown key '" + std::string(kv.key) + "' (known: fmt, width, height, fps, exposure, buffers)");
    }
  }
  return v;
}

GpioLaserSpec parse_gpio_laser_spec(std::string_view spec) {
  if (spec.substr(0, 5) != "gpio:") bad(spec, "a GPIO laser spec starts with 'gpio:'");
  auto parts = split_colon(spec, spec.substr(5), 2);
  if (parts.size() != 2) bad(spec, "expected gpio:CHIP:line=L[,active_low=1]");
  GpioLaserSpec g;
  g.chip = std::string(parts[0]);
  for (const auto& kv : split_kv(spec, parts[1])) {
    if (kv.key == "line")
      g.line = line_ref(spec, kv);
    else if (kv.key == "active_low")
      g.active_low = flag(spec, kv);
    else
      bad(spec, "unknown key '" + std::string(kv.key) + "' (known: line, active_low)");
  }
  if (!g.line.valid()) bad(spec, "missing 'line='");
  return g;
}

std::unique_ptr<Laser> make_gpio_laser(std::string_view spec) {
  return open_gpiod_laser(parse_gpio_laser_spec(spec));
}

GpioBackend make_gpio_backend(std::string_view spec) {
  auto lines = GpiodLines::open(parse_gpio_spec(spec));
  GpioBackend b;
  if (lines->has_laser()) b.laser = std::make_unique<GpiodLaser>(lines);
  b.lines = std::move(lines);
  return b;
}

Cia402Config cia402_config(const CanSpec& c) {
  Cia402Config m;
  m.node = c.node;
  m.heartbeat_ms = c.heartbeat_ms;
  m.velocity = c.velocity;
  m.acceleration = c.acceleration;
  m.sdo_timeout = static_cast<Nanos>(c.sdo_timeout_ms) * 1'000'000;
  m.state_timeout = static_cast<Nanos>(c.state_timeout_ms) * 1'000'000;
  return m;
}

std::unique_ptr<Galvo> make_can_galvo(std::string_view spec) {
  const CanSpec c = parse_can_spec(spec);
  if (c.iface.empty()) bad(spec, "sim-can is the hw-sim drive twin (facetscan-fw-hil), not a CAN interface");
  return CanGalvo::open(c.iface, cia402_config(c));
}

std::unique_ptr<Camera> make_v4l2_camera(std::string_view spec) {
  return std::make_unique<V4l2Camera>(parse_v4l2_spec(spec));
}

}  // namespace fs::fw
