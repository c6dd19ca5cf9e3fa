#pragma once
// Shared helpers of the libgpiod backends (not part of the public interface).
#include <time.h>

#include <array>
#include <cstdint>
#include <string>

#include "firmware/backends/factory.hpp"
#include "firmware/device/gpio_lines.hpp"

namespace fs::fw::gpiod_detail {

// Output slots inside the request.
enum Slot : int { kStep = 0, kDir = 1, kEnable = 2, kLaser = 3 };

inline std::string line_text(const GpioLineRef& r) {
  return r.offset >= 0 ? std::to_string(r.offset) : r.name;
}

// Small fixed ring of home edges (no allocation).
class EdgeRing {
 public:
  bool push(const GpioEdge& e) {
    if (tail_ - head_ >= buf_.size()) {
      ++overflow_;
      return false;
    }
    buf_[tail_++ % buf_.size()] = e;
    return true;
  }
  bool pop(GpioEdge& e) {
    if (head_ == tail_) return false;
    e = buf_[head_++ % buf_.size()];
    return true;
  }
  std::uint64_t overflow() const { return overflow_; }

 private:
  std::array<GpioEdge, 64> buf_{};
  std::uint64_t head_ = 0, tail_ = 0, overflow_ = 0;
};

}  // namespace fs::fw::gpiod_detail
