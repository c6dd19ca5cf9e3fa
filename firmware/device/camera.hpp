#pragma once
// The stripe camera. grab() hands out a view of a driver buffer (zero copy) until release().
#include <cstdint>

#include "firmware/device/clock.hpp"

namespace fs::fw {

enum class PixelFormat : std::uint8_t { Mono8 = 0, Mono16 = 1, Yuyv = 2 /* luma = even bytes */ };

struct FrameView {
  const std::uint8_t* data = nullptr;
  std::uint32_t width = 0, height = 0;
  std::uint32_t stride = 0;  // bytes per row
  PixelFormat format = PixelFormat::Mono8;
  std::uint32_t sequence = 0;  // driver sequence number (gaps = dropped frames)
  Nanos timestamp = 0;         // exposure time, same clock as Clock::now()
  std::int32_t buffer = -1;    // driver buffer index, for release()
};

enum class GrabResult : std::uint8_t { Ok = 0, Timeout, Error };

class Camera {
 public:
  virtual ~Camera() = default;
  virtual void start(Nanos now) = 0;
  virtual void stop() noexcept = 0;
  // Waits for the next frame until the absolute deadline.
  virtual GrabResult grab(Nanos deadline, FrameView& out) = 0;
  virtual void release(const FrameView& frame) = 0;
  virtual std::uint32_t frames_dropped() const = 0;
};

}  // namespace fs::fw
