// GpiodLines on libgpiod 1.x (v1 C API, kernel GPIO uAPI v1). Selected by CMake when libgpiod < 2.0.
#include <gpiod.h>
#include <poll.h>

#include <cerrno>
#include <cstring>

#include "common/error.hpp"
#include "firmware/backends/gpiod_lines.hpp"
#include "firmware/backends/gpiod_lines_common.hpp"

namespace fs::fw {
namespace {

using namespace gpiod_detail;

class GpiodLinesV1 final : public GpiodLines {
 public:
  explicit GpiodLinesV1(const GpioSpec& spec) : spec_(spec) {
    chip_ = ::gpiod_chip_open_lookup(spec.chip.c_str());
    if (!chip_) fail("cannot open GPIO chip (gpiod_chip_open_lookup)");
    try {
      request();
    } catch (...) {
      ::gpiod_chip_close(chip_);  // releases whatever was requested
      chip_ = nullptr;
      throw;
    }
  }

  void request() {
    const GpioSpec& spec = spec_;
    gpiod_line_bulk_init(&out_);
    add_output(spec.step, "step");
    add_output(spec.dir, "dir");
    add_output(spec.enable, "en");
    if (spec.laser.valid()) add_output(spec.laser, "laser");
    values_.fill(0);
    values_[kEnable] = phys_enable(false);
    if (::gpiod_line_request_bulk_output(&out_, "facetscan", values_.data()) < 0)
      fail("cannot request output lines step/dir/en" + std::string(spec.laser.valid() ? "/laser" : "") +
           " (busy or invalid?)");
    home_ = find(spec.home, "home");
    const int flags = spec.home_active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
    if (::gpiod_line_request_both_edges_events_flags(home_, "facetscan", flags) < 0)
      fail("cannot request home line " + line_text(spec.home) + " for edge events");
    last_write_ = monotonic_now();
  }

  ~GpiodLinesV1() override {
    safe();
    if (chip_) ::gpiod_chip_close(chip_);  // releases every requested line
  }

  void set_step(bool level, Nanos) override {
    if (level && !values_[kStep]) ++pulses_;
    write(kStep, level);
  }
  void set_dir(bool level, Nanos) override { write(kDir, level); }
  void set_enable(bool level, Nanos) override { write(kEnable, phys_enable(level)); }
  bool read_home(Nanos) override {
    int v = ::gpiod_line_get_value(home_);
    if (v < 0) fail("cannot read home line");
    return v != 0;
  }
  bool next_home_edge(GpioEdge& edge) override {
    drain();
    return edges_.pop(edge);
  }
  void safe() noexcept override {
    if (!chip_) return;
    values_[kStep] = 0;
    values_[kEnable] = phys_enable(false);
    if (spec_.laser.valid()) values_[kLaser] = 0;
    ::gpiod_line_set_value_bulk(&out_, values_.data());
  }

  bool has_laser() const override { return spec_.laser.valid(); }
  void set_laser(bool on, Nanos) override {
    if (!has_laser()) throw Error("GPIO chip '" + spec_.chip + "': no laser line configured (laser=)");
    write(kLaser, on);
  }
  bool laser_on() const override { return has_laser() && values_[kLaser]; }
  int home_event_fd() const override { return ::gpiod_line_event_get_fd(home_); }
  std::uint64_t step_pulses() const override { return pulses_; }
  Nanos last_write() const override { return last_write_; }
  std::string describe() const override {
    std::string s = std::string(::gpiod_chip_name(chip_)) + " [" + ::gpiod_chip_label(chip_) +
                    "]: step=" + line_text(spec_.step) + " dir=" + line_text(spec_.dir) +
                    " en=" + line_text(spec_.enable) + " home=" + line_text(spec_.home);
    if (has_laser()) s += " laser=" + line_text(spec_.laser);
    return s + " (libgpiod v1 API)";
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw Error("GPIO chip '" + spec_.chip + "': " + what + ": " + std::strerror(errno));
  }
  int phys_enable(bool on) const { return (on != spec_.enable_active_low) ? 1 : 0; }
  gpiod_line* find(const GpioLineRef& r, const char* role) {
    gpiod_line* l = r.offset >= 0 ? ::gpiod_chip_get_line(chip_, static_cast<unsigned>(r.offset))
                                  : ::gpiod_chip_find_line(chip_, r.name.c_str());
    if (!l) fail(std::string("no line ") + line_text(r) + " for " + role);
    return l;
  }
  void add_output(const GpioLineRef& r, const char* role) { gpiod_line_bulk_add(&out_, find(r, role)); }
  void write(int slot, bool level) {
    values_[slot] = level ? 1 : 0;
    // The v1 handle ioctl sets every line of the request at once: always write the whole set.
    if (::gpiod_line_set_value_bulk(&out_, values_.data()) < 0) fail("cannot set output lines");
    last_write_ = monotonic_now();
  }
  void drain() {
    const int fd = ::gpiod_line_event_get_fd(home_);
    for (int i = 0; i < 64; ++i) {
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, 0) <= 0 || !(p.revents & POLLIN)) return;
      gpiod_line_event ev{};
      if (::gpiod_line_event_read(home_, &ev) < 0) {
        if (errno == EINTR) continue;
        fail("cannot read home edge event");
      }
      edges_.push({Nanos(ev.ts.tv_sec) * 1'000'000'000 + ev.ts.tv_nsec,
                   ev.event_type == GPIOD_LINE_EVENT_RISING_EDGE});
    }
  }

  GpioSpec spec_;
  gpiod_chip* chip_ = nullptr;
  gpiod_line_bulk out_{};
  gpiod_line* home_ = nullptr;
  std::array<int, 4> values_{};
  EdgeRing edges_;
  std::uint64_t pulses_ = 0;
  Nanos last_write_ = 0;
};

class GpiodLaserLineV1 final : public Laser {
 public:
  explicit GpiodLaserLineV1(const GpioLaserSpec& spec) : spec_(spec) {
    chip_ = ::gpiod_chip_open_lookup(spec.chip.c_str());
    if (!chip_) fail("cannot open GPIO chip (gpiod_chip_open_lookup)");
    line_ = spec.line.offset >= 0 ? ::gpiod_chip_get_line(chip_, static_cast<unsigned>(spec.line.offset))
                                  : ::gpiod_chip_find_line(chip_, spec.line.name.c_str());
    const int flags = spec.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
    if (!line_ || ::gpiod_line_request_output_flags(line_, "facetscan", flags, 0) < 0) {
      ::gpiod_chip_close(chip_);
      chip_ = nullptr;
      fail("cannot request laser line " + line_text(spec.line));
    }
  }
  ~GpiodLaserLineV1() override {
    force_off();
    if (chip_) ::gpiod_chip_close(chip_);
  }
  void set(bool on, Nanos) override {
    if (::gpiod_line_set_value(line_, on ? 1 : 0) < 0) fail("cannot set laser line");
    on_ = on;
  }
  bool is_on() const override { return on_; }
  void force_off() noexcept override {
    if (line_) ::gpiod_line_set_value(line_, 0);
    on_ = false;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw Error("GPIO chip '" + spec_.chip + "': " + what + ": " + std::strerror(errno));
  }
  GpioLaserSpec spec_;
  gpiod_chip* chip_ = nullptr;
  gpiod_line* line_ = nullptr;
  bool on_ = false;
};

}  // namespace

std::unique_ptr<Laser> open_gpiod_laser(const GpioLaserSpec& spec) {
  return std::make_unique<GpiodLaserLineV1>(spec);
}

std::shared_ptr<GpiodLines> GpiodLines::open(const GpioSpec& spec) {
  return std::make_shared<GpiodLinesV1>(spec);
}
int GpiodLines::api_version() { return 1; }

}  // namespace fs::fw
