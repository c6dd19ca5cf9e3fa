#pragma once
// The simulated scanner hardware of the two VM scans (vm_scene_scan_test.cpp, vm_loop_scan_test.cpp) behind
// the real kernel drivers: the CiA 402 drive twin answering on vcan0, polled every 1 ms on a thread of its
// own, and the output side of v4l2loopback's /dev/video10, into which each test's camera thread writes
// rendered frames.
#include <fcntl.h>
#include <linux/can.h>
#include <linux/videodev2.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "firmware/backends/can_port.hpp"
#include "firmware/loop/monotonic_clock.hpp"
#include "hw-sim/can/cia402_twin.hpp"

namespace fs::vmtest {

// The drive twin (node 1) on vcan0 from start_position, polled at 1 kHz until it is destroyed (a late wake-up
// longer than 100 ms restarts the schedule instead of polling in a burst). position(): where the twin's
// mirror is now. Destroy it after every thread that reads position().
class VcanDriveTwin {
 public:
  VcanDriveTwin(fw::MonotonicClock& clock, double start_position)
      : port_(open_port()), twin_(port_.fd(), clock, config(start_position)), position_(start_position) {
    twin_.set_position_callback([this](double p, std::int64_t) { position_ = p; });
    thread_ = std::jthread([this, &clock](std::stop_token stop) {
      constexpr fw::Nanos kMs = 1'000'000;
      fw::Nanos next = clock.now();
      while (!stop.stop_requested()) {
        next += kMs;
        clock.sleep_until(next);
        if (clock.now() - next > 100 * kMs) next = clock.now();
        twin_.poll();
      }
    });
  }
  double position() const { return position_.load(); }

 private:
  static fw::CanPort open_port() {
    constexpr canid_t m = CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG;
    const can_filter filters[] = {{0x000, m}, {0x601, m}, {0x201, m}};  // NMT, SDO and RPDO1 to node 1
    return fw::CanPort::open_raw("vcan0", filters);
  }
  static sim::Cia402TwinConfig config(double start_position) {
    sim::Cia402TwinConfig c;
    c.start_position = start_position;
    return c;
  }
  fw::CanPort port_;
  sim::Cia402Twin twin_;
  std::atomic<double> position_;
  std::jthread thread_;  // last: stopped and joined first
};

// /dev/video10's output side set to width x height in `fourcc` (GREY or YUYV) with `first_frame` written (a
// capture can start before the first render; the two-argument form: GREY and a black frame), closed when
// destroyed: declare it before the thread that writes into it. fd() is -1 on failure, and error() says which
// step failed.
class LoopbackOutput {
 public:
  LoopbackOutput(std::uint32_t width, std::uint32_t height)
      : LoopbackOutput(width, height, V4L2_PIX_FMT_GREY,
                       std::vector<std::uint8_t>(std::size_t(width) * height, 0)) {}
  LoopbackOutput(std::uint32_t width, std::uint32_t height, std::uint32_t fourcc,
                 std::span<const std::uint8_t> first_frame)
      : fd_(::open("/dev/video10", O_RDWR)) {
    if (fd_ < 0) {
      error_ = std::string("open /dev/video10: ") + std::strerror(errno);
      return;
    }
    const std::uint32_t bytes_per_pixel = fourcc == V4L2_PIX_FMT_YUYV ? 2 : 1;
    v4l2_format f{};
    f.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    f.fmt.pix.width = width;
    f.fmt.pix.height = height;
    f.fmt.pix.pixelformat = fourcc;
    f.fmt.pix.field = V4L2_FIELD_NONE;
    f.fmt.pix.bytesperline = width * bytes_per_pixel;
    f.fmt.pix.sizeimage = width * height * bytes_per_pixel;
    if (::ioctl(fd_, VIDIOC_S_FMT, &f) != 0)
      error_ = std::string("VIDIOC_S_FMT on /dev/video10: ") + std::strerror(errno);
    else if (::write(fd_, first_frame.data(), first_frame.size()) != static_cast<ssize_t>(first_frame.size()))
      error_ = std::string("first frame into /dev/video10: ") + std::strerror(errno);
    if (!error_.empty()) {
      ::close(fd_);
      fd_ = -1;
    }
  }
  ~LoopbackOutput() {
    if (fd_ >= 0) ::close(fd_);
  }
  LoopbackOutput(const LoopbackOutput&) = delete;
  LoopbackOutput& operator=(const LoopbackOutput&) = delete;
  int fd() const { return fd_; }
  const std::string& error() const { return error_; }

 private:
  int fd_;
  std::string error_;
};

}  // namespace fs::vmtest
