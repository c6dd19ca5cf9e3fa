// GpiodLines on libgpiod 2.x (v2 C API, kernel GPIO uAPI v2). Selected by CMake when libgpiod >= 2.0; written
// against the libgpiod 2.1 API (gpiod_chip_request_lines, gpiod_line_settings, gpiod_edge_event_buffer).
#include <dirent.h>
#include <gpiod.h>

#include <cerrno>
#include <cstring>

#include "common/error.hpp"
#include "firmware/backends/gpiod_lines.hpp"
#include "firmware/backends/gpiod_lines_common.hpp"

namespace fs::fw {
namespace {

using namespace gpiod_detail;

bool is_number(const std::string& s) {
  return !s.empty() && s.find_first_not_of("0123456789") == std::string::npos;
}

// CHIP: a path, gpiochipN, a number, or a chip label (searched among /dev/gpiochip*). nullptr (errno set) if
// none.
gpiod_chip* open_chip_v2(const std::string& c, std::string& path) {
  if (!c.empty() && c[0] == '/')
    path = c;
  else if (is_number(c))
    path = "/dev/gpiochip" + c;
  else if (c.rfind("gpiochip", 0) == 0)
    path = "/dev/" + c;
  if (!path.empty()) return ::gpiod_chip_open(path.c_str());
  DIR* d = ::opendir("/dev");
  if (!d) return nullptr;
  gpiod_chip* found = nullptr;
  while (dirent* e = ::readdir(d)) {
    if (std::strncmp(e->d_name, "gpiochip", 8) != 0) continue;
    const std::string p = std::string("/dev/") + e->d_name;
    gpiod_chip* chip = ::gpiod_chip_open(p.c_str());
    if (!chip) continue;
    gpiod_chip_info* info = ::gpiod_chip_get_info(chip);
    const bool match = info && c == ::gpiod_chip_info_get_label(info);
    if (info) ::gpiod_chip_info_free(info);
    if (match) {
      found = chip;
      path = p;
      break;
    }
    ::gpiod_chip_close(chip);
  }
  ::closedir(d);
  if (!found) errno = ENODEV;
  return found;
}

class GpiodLinesV2 final : public GpiodLines {
 public:
  explicit GpiodLinesV2(const GpioSpec& spec) : spec_(spec) {
    chip_ = open_chip(spec.chip);
    try {
      request();
    } catch (...) {
      release();
      throw;
    }
    last_write_ = monotonic_now();
  }
  ~GpiodLinesV2() override {
    safe();
    release();
  }

  void set_step(bool level, Nanos) override {
    if (level && !values_[kStep]) ++pulses_;
    write(kStep, level);
  }
  void set_dir(bool level, Nanos) override { write(kDir, level); }
  void set_enable(bool level, Nanos) override { write(kEnable, level != spec_.enable_active_low); }
  bool read_home(Nanos) override {
    const gpiod_line_value v = ::gpiod_line_request_get_value(req_, offsets_[4]);
    if (v == GPIOD_LINE_VALUE_ERROR) fail("cannot read home line");
    return v == GPIOD_LINE_VALUE_ACTIVE;
  }
  bool next_home_edge(GpioEdge& edge) override {
    drain();
    return edges_.pop(edge);
  }
  void safe() noexcept override {
    if (!req_) return;
    values_[kStep] = false;
    values_[kEnable] = spec_.enable_active_low;
    ::gpiod_line_request_set_value(req_, offsets_[kStep], GPIOD_LINE_VALUE_INACTIVE);
    ::gpiod_line_request_set_value(
        req_, offsets_[kEnable],
        spec_.enable_active_low ? GPIOD_LINE_VALUE_ACTIVE : GPIOD_LINE_VALUE_INACTIVE);
    if (has_laser()) {
      values_[kLaser] = false;
      ::gpiod_line_request_set_value(req_, offsets_[kLaser], GPIOD_LINE_VALUE_INACTIVE);
    }
  }
  bool has_laser() const override { return spec_.laser.valid(); }
  void set_laser(bool on, Nanos) override {
    if (!has_laser()) throw Error("GPIO chip '" + spec_.chip + "': no laser line configured (laser=)");
    write(kLaser, on);
  }
  bool laser_on() const override { return has_laser() && values_[kLaser]; }
  int home_event_fd() const override { return ::gpiod_line_request_get_fd(req_); }
  std::uint64_t step_pulses() const override { return pulses_; }
  Nanos last_write() const override { return last_write_; }
  std::string describe() const override {
    std::string s = path_ + ": step=" + std::to_string(offsets_[kStep]) +
                    " dir=" + std::to_string(offsets_[kDir]) + " en=" + std::to_string(offsets_[kEnable]) +
                    " home=" + std::to_string(offsets_[4]);
    if (has_laser()) s += " laser=" + std::to_string(offsets_[kLaser]);
    return s + " (libgpiod v2 API)";
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw Error("GPIO chip '" + spec_.chip + "': " + what + ": " + std::strerror(errno));
  }

  gpiod_chip* open_chip(const std::string& c) {
    gpiod_chip* chip = open_chip_v2(c, path_);
    if (!chip)
      fail(path_.empty() ? std::string("no GPIO chip with this path, number or label")
                         : "cannot open " + path_);
    return chip;
  }

  unsigned offset_of(const GpioLineRef& r, const char* role) {
    if (r.offset >= 0) return static_cast<unsigned>(r.offset);
    const int off = ::gpiod_chip_get_line_offset_from_name(chip_, r.name.c_str());
    if (off < 0) fail(std::string("no line named '") + r.name + "' for " + role);
    return static_cast<unsigned>(off);
  }

  void request() {
    offsets_[kStep] = offset_of(spec_.step, "step");
    offsets_[kDir] = offset_of(spec_.dir, "dir");
    offsets_[kEnable] = offset_of(spec_.enable, "en");
    if (has_laser()) offsets_[kLaser] = offset_of(spec_.laser, "laser");
    offsets_[4] = offset_of(spec_.home, "home");

    gpiod_line_settings* out = ::gpiod_line_settings_new();
    gpiod_line_settings* en = ::gpiod_line_settings_new();
    gpiod_line_settings* in = ::gpiod_line_settings_new();
    gpiod_line_config* lcfg = ::gpiod_line_config_new();
    gpiod_request_config* rcfg = ::gpiod_request_config_new();
    auto cleanup = [&] {
      if (out) ::gpiod_line_settings_free(out);
      if (en) ::gpiod_line_settings_free(en);
      if (in) ::gpiod_line_settings_free(in);
      if (lcfg) ::gpiod_line_config_free(lcfg);
      if (rcfg) ::gpiod_request_config_free(rcfg);
    };
    if (!out || !en || !in || !lcfg || !rcfg) {
      cleanup();
      fail("out of memory building the line request");
    }
    ::gpiod_line_settings_set_direction(out, GPIOD_LINE_DIRECTION_OUTPUT);
    ::gpiod_line_settings_set_output_value(out, GPIOD_LINE_VALUE_INACTIVE);
    ::gpiod_line_settings_set_direction(en, GPIOD_LINE_DIRECTION_OUTPUT);
    ::gpiod_line_settings_set_output_value(
        en, spec_.enable_active_low ? GPIOD_LINE_VALUE_ACTIVE : GPIOD_LINE_VALUE_INACTIVE);
    ::gpiod_line_settings_set_direction(in, GPIOD_LINE_DIRECTION_INPUT);
    ::gpiod_line_settings_set_edge_detection(in, GPIOD_LINE_EDGE_BOTH);
    ::gpiod_line_settings_set_event_clock(in, GPIOD_LINE_CLOCK_MONOTONIC);
    ::gpiod_line_settings_set_active_low(in, spec_.home_active_low);
    unsigned outs[3] = {offsets_[kStep], offsets_[kDir], offsets_[kLaser]};
    int rc = ::gpiod_line_config_add_line_settings(lcfg, outs, 2, out);
    if (rc == 0 && has_laser()) rc = ::gpiod_line_config_add_line_settings(lcfg, outs + 2, 1, out);
    if (rc == 0) rc = ::gpiod_line_config_add_line_settings(lcfg, &offsets_[kEnable], 1, en);
    if (rc == 0) rc = ::gpiod_line_config_add_line_settings(lcfg, &offsets_[4], 1, in);
    ::gpiod_request_config_set_consumer(rcfg, "facetscan");
    ::gpiod_request_config_set_event_buffer_size(rcfg, 64);
    if (rc == 0) req_ = ::gpiod_chip_request_lines(chip_, rcfg, lcfg);
    cleanup();
    if (rc != 0 || !req_) fail("cannot request step/dir/en/home lines in one request (busy or invalid?)");
    events_ = ::gpiod_edge_event_buffer_new(16);
    if (!events_) fail("cannot allocate the edge event buffer");
    values_[kEnable] = spec_.enable_active_low;
  }

  void release() noexcept {
    if (events_) ::gpiod_edge_event_buffer_free(events_);
    if (req_) ::gpiod_line_request_release(req_);
    if (chip_) ::gpiod_chip_close(chip_);
    events_ = nullptr;
    req_ = nullptr;
    chip_ = nullptr;
  }

  void write(int slot, bool level) {
    values_[slot] = level;
    if (::gpiod_line_request_set_value(req_, offsets_[slot],
                                       level ? GPIOD_LINE_VALUE_ACTIVE : GPIOD_LINE_VALUE_INACTIVE) < 0)
      fail("cannot set output line " + std::to_string(offsets_[slot]));
    last_write_ = monotonic_now();
  }

  void drain() {
    for (int round = 0; round < 4; ++round) {
      const int ready = ::gpiod_line_request_wait_edge_events(req_, 0);
      if (ready < 0) {
        if (errno == EINTR) continue;
        fail("cannot wait for home edge events");
      }
      if (ready == 0) return;
      const int n = ::gpiod_line_request_read_edge_events(req_, events_, 16);
      if (n < 0) fail("cannot read home edge events");
      for (int i = 0; i < n; ++i) {
        gpiod_edge_event* ev = ::gpiod_edge_event_buffer_get_event(events_, static_cast<unsigned long>(i));
        if (!ev) continue;
        edges_.push({static_cast<Nanos>(::gpiod_edge_event_get_timestamp_ns(ev)),
                     ::gpiod_edge_event_get_event_type(ev) == GPIOD_EDGE_EVENT_RISING_EDGE});
      }
    }
  }

  GpioSpec spec_;
  std::string path_;
  gpiod_chip* chip_ = nullptr;
  gpiod_line_request* req_ = nullptr;
  gpiod_edge_event_buffer* events_ = nullptr;
  unsigned offsets_[5] = {0, 0, 0, 0, 0};  // step, dir, en, laser, home
  bool values_[4] = {false, false, false, false};
  EdgeRing edges_;
  std::uint64_t pulses_ = 0;
  Nanos last_write_ = 0;
};

class GpiodLaserLineV2 final : public Laser {
 public:
  explicit GpiodLaserLineV2(const GpioLaserSpec& spec) : spec_(spec) {
    GpioSpec g;  // reuse the chip lookup (path, number, gpiochipN or label)
    g.chip = spec.chip;
    chip_ = open_chip_v2(g.chip, path_);
    if (!chip_) fail("no GPIO chip with this path, number or label");
    int off = spec.line.offset;
    if (off < 0) off = ::gpiod_chip_get_line_offset_from_name(chip_, spec.line.name.c_str());
    if (off < 0) {
      release();
      fail("no line named '" + spec.line.name + "' for the laser");
    }
    offset_ = static_cast<unsigned>(off);
    gpiod_line_settings* ls = ::gpiod_line_settings_new();
    gpiod_line_config* lc = ::gpiod_line_config_new();
    gpiod_request_config* rc = ::gpiod_request_config_new();
    int r = (ls && lc && rc) ? 0 : -1;
    if (r == 0) {
      ::gpiod_line_settings_set_direction(ls, GPIOD_LINE_DIRECTION_OUTPUT);
      ::gpiod_line_settings_set_output_value(ls, GPIOD_LINE_VALUE_INACTIVE);
      ::gpiod_line_settings_set_active_low(ls, spec.active_low);
      r = ::gpiod_line_config_add_line_settings(lc, &offset_, 1, ls);
      ::gpiod_request_config_set_consumer(rc, "facetscan");
    }
    if (r == 0) req_ = ::gpiod_chip_request_lines(chip_, rc, lc);
    if (ls) ::gpiod_line_settings_free(ls);
    if (lc) ::gpiod_line_config_free(lc);
    if (rc) ::gpiod_request_config_free(rc);
    if (!req_) {
      release();
      fail("cannot request laser line " + line_text(spec.line));
    }
  }
  ~GpiodLaserLineV2() override {
    force_off();
    release();
  }
  void set(bool on, Nanos) override {
    if (::gpiod_line_request_set_value(req_, offset_,
                                       on ? GPIOD_LINE_VALUE_ACTIVE : GPIOD_LINE_VALUE_INACTIVE) < 0)
      fail("cannot set laser line");
    on_ = on;
  }
  bool is_on() const override { return on_; }
  void force_off() noexcept override {
    if (req_) ::gpiod_line_request_set_value(req_, offset_, GPIOD_LINE_VALUE_INACTIVE);
    on_ = false;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw Error("GPIO chip '" + spec_.chip + "': " + what + ": " + std::strerror(errno));
  }
  void release() noexcept {
    if (req_) ::gpiod_line_request_release(req_);
    if (chip_) ::gpiod_chip_close(chip_);
    req_ = nullptr;
    chip_ = nullptr;
  }
  GpioLaserSpec spec_;
  std::string path_;
  gpiod_chip* chip_ = nullptr;
  gpiod_line_request* req_ = nullptr;
  unsigned offset_ = 0;
  bool on_ = false;
};

}  // namespace

std::unique_ptr<Laser> open_gpiod_laser(const GpioLaserSpec& spec) {
  return std::make_unique<GpiodLaserLineV2>(spec);
}

std::shared_ptr<GpiodLines> GpiodLines::open(const GpioSpec& spec) {
  return std::make_shared<GpiodLinesV2>(spec);
}
int GpiodLines::api_version() { return 2; }

}  // namespace fs::fw
