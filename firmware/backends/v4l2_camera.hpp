#pragma once
// Camera on a V4L2 capture device: QUERYCAP, S_FMT (GREY / Y16 / YUYV, luma = even bytes), frame rate (S_PARM
// when the driver has V4L2_CAP_TIMEPERFRAME), manual exposure when V4L2_CID_EXPOSURE_ABSOLUTE exists, MMAP
// streaming with >= 4 buffers, poll + DQBUF / QBUF (EINTR and EAGAIN retried), sequence gaps counted as
// dropped frames, buffers flagged V4L2_BUF_FLAG_ERROR or short re-queued and counted, timestamps used only
// when the driver flags them CLOCK_MONOTONIC (else the dequeue time, counted). Zero copy: FrameView::data
// points into the mmap'ed driver buffer until release(). grab() does not allocate.
#include <linux/videodev2.h>

#include <array>
#include <cstdint>
#include <string>

#include "firmware/backends/factory.hpp"
#include "firmware/backends/v4l2_device.hpp"
#include "firmware/device/camera.hpp"
#include "firmware/device/clock.hpp"

namespace fs::fw {

struct V4l2Stats {
  std::uint64_t frames = 0;
  std::uint64_t dropped = 0;            // sequence gaps
  std::uint64_t sequence_restarts = 0;  // sequence went back or repeated (not counted as drops)
  std::uint64_t error_buffers = 0;      // V4L2_BUF_FLAG_ERROR or bytesused too small
  std::uint64_t non_monotonic = 0;      // frames whose timestamp was not CLOCK_MONOTONIC
  std::uint64_t eintr = 0, eagain = 0;  // retried system calls
};

class V4l2Camera final : public Camera {
 public:
  static constexpr std::uint32_t kMaxBuffers = 32;

  // Opens and configures the device; throws fs::Error naming the device and the failing step.
  // clock: time base of deadlines (nullptr: CLOCK_MONOTONIC, the clock of V4L2 timestamps).
  explicit V4l2Camera(const V4l2Spec& spec, V4l2Io& io = system_v4l2_io(), Clock* clock = nullptr);
  ~V4l2Camera() override;
  V4l2Camera(const V4l2Camera&) = delete;
  V4l2Camera& operator=(const V4l2Camera&) = delete;

  void start(Nanos now) override;
  void stop() noexcept override;
  GrabResult grab(Nanos deadline, FrameView& out) override;
  void release(const FrameView& frame) override;
  std::uint32_t frames_dropped() const override { return static_cast<std::uint32_t>(stats_.dropped); }

  std::uint32_t width() const { return width_; }
  std::uint32_t height() const { return height_; }
  std::uint32_t stride() const { return stride_; }
  PixelFormat format() const { return format_; }
  std::uint32_t buffer_count() const { return nbuf_; }
  const V4l2Stats& stats() const { return stats_; }
  const std::string& driver() const { return driver_; }
  // What could not be applied (no frame-rate control, no exposure control), "" when everything was.
  const std::string& notes() const { return notes_; }
  // True if `p` lies inside one of the mmap'ed driver buffers (zero-copy check).
  bool owns_pointer(const void* p) const;

 private:
  [[noreturn]] void fail(const std::string& what) const;
  int xioctl(unsigned long req, void* arg);
  void configure();
  void set_exposure();
  void set_frame_rate();
  void queue(std::uint32_t index);
  Nanos now() const;

  V4l2Spec spec_;
  V4l2Io& io_;
  Clock* clock_;
  int fd_ = -1;
  std::string driver_, notes_;
  std::uint32_t width_ = 0, height_ = 0, stride_ = 0, sizeimage_ = 0, fourcc_ = 0;
  PixelFormat format_ = PixelFormat::Mono8;
  struct Buffer {
    void* addr = nullptr;
    std::size_t length = 0;
    bool queued = false;
    bool out = false;  // handed out in a FrameView
  };
  std::array<Buffer, kMaxBuffers> bufs_{};
  std::uint32_t nbuf_ = 0;
  bool streaming_ = false;
  bool have_seq_ = false;
  std::uint32_t last_seq_ = 0;
  V4l2Stats stats_;
};

}  // namespace fs::fw
