#include "firmware/backends/device_check.hpp"

#include <fcntl.h>
#include <linux/gpio.h>
#include <linux/videodev2.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <fmt/core.h>
#include <cerrno>
#include <cstring>
#include <filesystem>

#include "common/cia402_protocol.hpp"
#include "common/error.hpp"
#include "firmware/loop/monotonic_clock.hpp"

namespace fs::fw {

namespace {

std::string errno_text() { return std::strerror(errno); }

class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }

 private:
  int fd_;
};

int xioctl(int fd, unsigned long req, void* arg) {
  int r;
  do {
    r = ::ioctl(fd, req, arg);
  } while (r < 0 && errno == EINTR);
  return r;
}

std::string cstr(const char* s, std::size_t n) { return std::string(s, strnlen(s, n)); }

bool all_digits(const std::string& s) {
  return !s.empty() && s.find_first_not_of("0123456789") == std::string::npos;
}

// Resolves the chip spec to a /dev path: a path, gpiochipN, N, or a label / name found among /dev/gpiochip*.
std::string resolve_chip(const std::string& chip, std::string& why) {
  if (!chip.empty() && chip[0] == '/') return chip;
  if (all_digits(chip)) return "/dev/gpiochip" + chip;
  if (chip.rfind("gpiochip", 0) == 0 && all_digits(chip.substr(8))) return "/dev/" + chip;
  std::error_code ec;
  std::string seen;
  for (const auto& e : std::filesystem::directory_iterator("/dev", ec)) {
    const std::string n = e.path().filename().string();
    if (n.rfind("gpiochip", 0) != 0) continue;
    Fd fd(::open(e.path().c_str(), O_RDWR | O_CLOEXEC));
    if (fd.get() < 0) continue;
    gpiochip_info info{};
    if (xioctl(fd.get(), GPIO_GET_CHIPINFO_IOCTL, &info) < 0) continue;
    const std::string label = cstr(info.label, sizeof info.label);
    seen += (seen.empty() ? "" : ", ") + n + " '" + label + "'";
    if (label == chip) return e.path().string();
  }
  why = "no GPIO chip labelled '" + chip + "' (chips: " + (seen.empty() ? "none" : seen) + ")";
  return {};
}

const char* cia402_state(std::uint16_t sw) {
  if ((sw & 0x4F) == 0x00) return "not ready to switch on";
  if ((sw & 0x4F) == 0x40) return "switch on disabled";
  if ((sw & 0x6F) == 0x21) return "ready to switch on";
  if ((sw & 0x6F) == 0x23) return "switched on";
  if ((sw & 0x6F) == 0x27) return "operation enabled";
  if ((sw & 0x6F) == 0x07) return "quick stop active";
  if ((sw & 0x4F) == 0x0F) return "fault reaction active";
  if ((sw & 0x4F) == 0x08) return "fault";
  return "unknown state";
}

const char* nmt_state(std::uint8_t s) {
  switch (s & 0x7F) {
    case cia402::kStateBoot:
      return "boot-up";
    case cia402::kStateStopped:
      return "stopped";
    case cia402::kStateOperational:
      return "operational";
    case 0x7F:
      return "pre-operational";
    default:
      return "unknown";
  }
}

std::uint32_t fourcc_of(V4l2Fourcc f) {
  switch (f) {
    case V4l2Fourcc::Y16:
      return V4L2_PIX_FMT_Y16;
    case V4l2Fourcc::Yuyv:
      return V4L2_PIX_FMT_YUYV;
    case V4l2Fourcc::Grey:
      break;
  }
  return V4L2_PIX_FMT_GREY;
}

std::string fourcc_text(std::uint32_t f) {
  std::string s;
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((f >> (8 * i)) & 0xFF);
    s += (c >= 32 && c < 127) ? c : '?';
  }
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

}  // namespace

bool CheckReport::ok() const { return !items.empty() && failed() == 0; }

std::size_t CheckReport::failed() const {
  std::size_t n = 0;
  for (const auto& i : items) n += i.ok ? 0 : 1;
  return n;
}

void CheckReport::add(std::string device, std::string what, bool ok, std::string detail) {
  items.push_back(CheckItem{std::move(device), std::move(what), ok, std::move(detail)});
}

std::string CheckReport::text() const {
  std::string s;
  for (const auto& i : items)
    s += fmt::format("  [{}] {}: {}: {}\n", i.ok ? " ok " : "MISS", i.device, i.what, i.detail);
  return s;
}

void check_gpio(CheckReport& r, const std::string& device, const std::string& chip,
                const std::vector<std::pair<std::string, GpioLineRef>>& lines) {
  const std::string what = "GPIO chip " + chip;
  std::string why;
  const std::string path = resolve_chip(chip, why);
  if (path.empty()) {
    r.add(device, what, false, why);
    return;
  }
  Fd fd(::open(path.c_str(), O_RDWR | O_CLOEXEC));
  if (fd.get() < 0) {
    r.add(device, what, false, "cannot open " + path + ": " + errno_text());
    return;
  }
  gpiochip_info info{};
  if (xioctl(fd.get(), GPIO_GET_CHIPINFO_IOCTL, &info) < 0) {
    r.add(device, what, false, path + " is not a GPIO chip (GPIO_GET_CHIPINFO_IOCTL: " + errno_text() + ")");
    return;
  }
  r.add(device, what, true,
        fmt::format("{} '{}' ({}), {} lines", path, cstr(info.label, sizeof info.label),
                    cstr(info.name, sizeof info.name), info.lines));
  for (const auto& [role, ref] : lines) {
    const std::string lwhat = fmt::format(
        "line {} = {}", role, ref.offset >= 0 ? std::to_string(ref.offset) : "'" + ref.name + "'");
    int offset = -1;
    gpioline_info li{};
    if (ref.offset >= 0) {
      if (static_cast<std::uint32_t>(ref.offset) >= info.lines) {
        r.add(device, lwhat, false,
              fmt::format("offset {} out of range: {} has {} lines", ref.offset, path, info.lines));
        continue;
      }
      li.line_offset = static_cast<std::uint32_t>(ref.offset);
      if (xioctl(fd.get(), GPIO_GET_LINEINFO_IOCTL, &li) < 0) {
        r.add(device, lwhat, false, "GPIO_GET_LINEINFO_IOCTL: " + errno_text());
        continue;
      }
      offset = ref.offset;
    } else {
      for (std::uint32_t o = 0; o < info.lines; ++o) {
        gpioline_info t{};
        t.line_offset = o;
        if (xioctl(fd.get(), GPIO_GET_LINEINFO_IOCTL, &t) == 0 && cstr(t.name, sizeof t.name) == ref.name) {
          li = t;
          offset = static_cast<int>(o);
          break;
        }
      }
      if (offset < 0) {
        r.add(device, lwhat, false, "no line named '" + ref.name + "' on " + path);
        continue;
      }
    }
    const std::string name = cstr(li.name, sizeof li.name);
    const std::string consumer = cstr(li.consumer, sizeof li.consumer);
    const bool used = (li.flags & GPIOLINE_FLAG_KERNEL) != 0;
    const std::string found = fmt::format("offset {}{}", offset, name.empty() ? "" : " '" + name + "'");
    if (used)
      r.add(device, lwhat, false,
            found + fmt::format(" is in use by '{}'", consumer.empty() ? std::string("kernel") : consumer));
    else
      r.add(device, lwhat, true, found + ", free");
  }
}

void check_can_drive(CheckReport& r, const std::string& device, const std::string& label, CanPort& port,
                     std::uint8_t node, Clock& clock, const std::function<void()>& service, Nanos timeout) {
  const std::string what = fmt::format("CiA 402 drive node {} on {}", node, label);
  int hb_state = -1;
  // One expedited SDO upload; returns false with `err` set on abort / timeout.
  auto sdo_read = [&](std::uint16_t index, std::uint32_t& value, std::string& err) {
    can_frame q{};
    q.can_id = cia402::kSdoRx + node;
    q.can_dlc = 8;
    q.data[0] = cia402::kSdoReadReq;
    q.data[1] = static_cast<std::uint8_t>(index & 0xFF);
    q.data[2] = static_cast<std::uint8_t>(index >> 8);
    port.send(q);
    const Nanos deadline = clock.now() + timeout;
    for (;;) {
      port.flush();
      if (service) service();
      can_frame f{};
      Nanos ts = 0;
      while (port.recv(f, ts)) {
        if (f.can_id & CAN_ERR_FLAG) continue;
        const std::uint32_t id = f.can_id & CAN_SFF_MASK;
        if (id == cia402::kHeartbeat + node && f.can_dlc >= 1) hb_state = f.data[0];
        if (id != cia402::kSdoTx + node || f.can_dlc < 8) continue;
        const std::uint16_t idx = static_cast<std::uint16_t>(f.data[1] | (f.data[2] << 8));
        if (idx != index || f.data[3] != 0) continue;
        const std::uint32_t v =
            static_cast<std::uint32_t>(f.data[4]) | (static_cast<std::uint32_t>(f.data[5]) << 8) |
            (static_cast<std::uint32_t>(f.data[6]) << 16) | (static_cast<std::uint32_t>(f.data[7]) << 24);
        if (f.data[0] == cia402::kSdoAbort) {
          err = fmt::format("SDO read of {:04X}h aborted with code {:08X}h", index, v);
          return false;
        }
        if ((f.data[0] & 0xE0) != cia402::kSdoReadResp || (f.data[0] & 0x03) != 0x03) {
          err =
              fmt::format("SDO read of {:04X}h: unexpected response command byte {:02X}h", index, f.data[0]);
          return false;
        }
        const int size = 4 - ((f.data[0] >> 2) & 3);
        value = size >= 4 ? v : (v & ((1u << (8 * size)) - 1));
        return true;
      }
      if (clock.now() >= deadline) break;
      pollfd p{port.fd(), POLLIN, 0};
      ::poll(&p, 1, 1);
    }
    err = fmt::format(
        "no answer to the SDO read of {:04X}h within {} ms (drive off, wrong node id or bitrate?)", index,
        timeout / 1'000'000);
    return false;
  };
  std::uint32_t device_type = 0, sw = 0;
  std::string err;
  if (!sdo_read(0x1000, device_type, err)) {
    r.add(device, what, false, err);
    return;
  }
  const std::uint16_t profile = device_type & 0xFFFF;
  r.add(device, what + ": device type (1000h)", profile == 402,
        fmt::format("{:08X}h{}", device_type,
                    profile == 402 ? " (CiA 402 drive)"
                                   : fmt::format(" (profile {}, not a CiA 402 drive)", profile)));
  if (!sdo_read(cia402::kStatusword, sw, err)) {
    r.add(device, what + ": statusword (6041h)", false, err);
    return;
  }
  const bool fault = (sw & 0x0008) != 0;
  r.add(device, what + ": statusword (6041h)", !fault,
        fmt::format("{:04X}h, {}{}", sw, cia402_state(static_cast<std::uint16_t>(sw)),
                    fault ? " (drive in fault: clear it before scanning)" : ""));
  if (hb_state >= 0)
    r.add(device, what + ": NMT", true,
          hb_state == cia402::kStateBoot
              ? std::string("boot-up message seen (node now pre-operational)")
              : fmt::format("heartbeat seen, state {}", nmt_state(static_cast<std::uint8_t>(hb_state))));
}

void check_v4l2(CheckReport& r, const std::string& device, const V4l2Spec& spec) {
  const std::string what = "V4L2 " + spec.device;
  Fd fd(::open(spec.device.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC));
  if (fd.get() < 0) {
    r.add(device, what, false, "cannot open " + spec.device + ": " + errno_text());
    return;
  }
  v4l2_capability cap{};
  if (xioctl(fd.get(), VIDIOC_QUERYCAP, &cap) < 0) {
    r.add(device, what, false, spec.device + " is not a V4L2 device (VIDIOC_QUERYCAP: " + errno_text() + ")");
    return;
  }
  const std::uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
  const bool capture = (caps & V4L2_CAP_VIDEO_CAPTURE) != 0, streaming = (caps & V4L2_CAP_STREAMING) != 0;
  r.add(device, what, capture && streaming,
        fmt::format("driver {}, card '{}'{}{}",
                    cstr(reinterpret_cast<const char*>(cap.driver), sizeof cap.driver),
                    cstr(reinterpret_cast<const char*>(cap.card), sizeof cap.card),
                    capture ? "" : ", NOT a video capture device", streaming ? "" : ", no streaming I/O"));
  if (!capture) return;
  std::string formats;
  bool have = false;
  const std::uint32_t want = fourcc_of(spec.format);
  for (std::uint32_t i = 0; i < 256; ++i) {
    v4l2_fmtdesc d{};
    d.index = i;
    d.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(fd.get(), VIDIOC_ENUM_FMT, &d) < 0) break;
    formats += (formats.empty() ? "" : " ") + fourcc_text(d.pixelformat);
    have = have || d.pixelformat == want;
  }
  r.add(device, what + ": format " + fourcc_text(want), have,
        (have ? "offered" : "not offered") + std::string("; formats (VIDIOC_ENUM_FMT): ") +
            (formats.empty() ? "none" : formats));
  if (!have) return;
  v4l2_format f{};
  f.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  f.fmt.pix.width = spec.width;
  f.fmt.pix.height = spec.height;
  f.fmt.pix.pixelformat = want;
  f.fmt.pix.field = V4L2_FIELD_NONE;
  if (xioctl(fd.get(), VIDIOC_TRY_FMT, &f) < 0) {
    r.add(device, what + fmt::format(": size {}x{}", spec.width, spec.height), false,
          "VIDIOC_TRY_FMT: " + errno_text());
    return;
  }
  const bool same =
      f.fmt.pix.width == spec.width && f.fmt.pix.height == spec.height && f.fmt.pix.pixelformat == want;
  r.add(device, what + fmt::format(": size {}x{}", spec.width, spec.height), same,
        same ? "accepted (VIDIOC_TRY_FMT)"
             : fmt::format("the driver gives {}x{} {} instead", f.fmt.pix.width, f.fmt.pix.height,
                           fourcc_text(f.fmt.pix.pixelformat)));
}

namespace {

void check_can_iface(CheckReport& r, const std::string& device, const CanSpec& cs) {
  const std::string what = "CAN interface " + cs.iface;
  if (::if_nametoindex(cs.iface.c_str()) == 0) {
    r.add(device, what, false, "no network interface '" + cs.iface + "' (" + errno_text() + ")");
    return;
  }
  Fd s(::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0));
  ifreq ifr{};
  std::snprintf(ifr.ifr_name, IFNAMSIZ, "%s", cs.iface.c_str());
  if (s.get() >= 0 && xioctl(s.get(), SIOCGIFFLAGS, &ifr) == 0 && !(ifr.ifr_flags & IFF_UP)) {
    r.add(device, what, false, "interface is down (ip link set " + cs.iface + " up)");
    return;
  }
  constexpr canid_t m = CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG;
  const can_filter filters[] = {{static_cast<canid_t>(cia402::kSdoTx + cs.node), m},
                                {static_cast<canid_t>(cia402::kHeartbeat + cs.node), m}};
  try {
    CanPort port = CanPort::open_raw(cs.iface, filters);
    r.add(device, what, true, "present and up");
    MonotonicClock clock;
    check_can_drive(r, device, cs.iface, port, cs.node, clock, {}, 300'000'000);
  } catch (const Error& e) {
    r.add(device, what, false, e.what());
  }
}

template <typename F>
void guarded(CheckReport& r, const std::string& device, const std::string& spec, F&& f) {
  try {
    f();
  } catch (const Error& e) {
    r.add(device, spec, false, e.what());
  }
}

}  // namespace

bool is_sim_galvo(const std::string& spec) { return spec == "sim" || spec.rfind("sim-can", 0) == 0; }
bool is_sim_camera(const std::string& spec) { return spec == "sim"; }

CheckReport check_devices(const std::string& galvo, const std::string& camera, const std::string& laser,
                          const SimChecks& sim) {
  CheckReport r;
  bool galvo_laser = false;  // the gpio galvo spec carries laser=
  const char* no_sim =
      "a simulated device: those are in facetscan-fw-hil (this binary has the real backends only)";
  guarded(r, "galvo", galvo, [&] {
    if (is_sim_galvo(galvo)) {
      if (sim.galvo)
        sim.galvo(r, galvo);
      else
        r.add("galvo", galvo, false, no_sim);
    } else if (galvo.rfind("gpio:", 0) == 0) {
      const GpioSpec g = parse_gpio_spec(galvo);
      std::vector<std::pair<std::string, GpioLineRef>> lines = {
          {"step", g.step}, {"dir", g.dir}, {"en", g.enable}, {"home", g.home}};
      if (g.laser.valid()) lines.emplace_back("laser", g.laser);
      galvo_laser = g.laser.valid();
      check_gpio(r, "galvo", g.chip, lines);
    } else if (galvo.rfind("can:", 0) == 0) {
      check_can_iface(r, "galvo", parse_can_spec(galvo));
    } else {
      r.add("galvo", galvo, false, "expected sim, sim-can[:...], gpio:... or can:...");
    }
  });
  guarded(r, "camera", camera, [&] {
    if (is_sim_camera(camera)) {
      if (sim.camera)
        sim.camera(r, camera);
      else
        r.add("camera", camera, false, no_sim);
    } else if (camera.rfind("v4l2:", 0) == 0) {
      check_v4l2(r, "camera", parse_v4l2_spec(camera));
    } else {
      r.add("camera", camera, false, "expected sim or v4l2:...");
    }
  });
  if (!laser.empty()) {
    guarded(r, "laser", laser, [&] {
      if (laser.rfind("gpio:", 0) != 0) {
        r.add("laser", laser, false, "expected gpio:CHIP:line=L[,active_low=1]");
        return;
      }
      const GpioLaserSpec l = parse_gpio_laser_spec(laser);
      check_gpio(r, "laser", l.chip, {{"laser", l.line}});
    });
  } else if (!is_sim_camera(camera) && !galvo_laser) {
    r.add("laser", "(none)", false,
          "no laser line: give --laser gpio:CHIP:line=L (or laser= in the gpio galvo)");
  }
  return r;
}

}  // namespace fs::fw
