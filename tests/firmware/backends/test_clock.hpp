#pragma once
// A manual clock for the backend tests: time moves only when the test says so.
#include "firmware/device/clock.hpp"

namespace fs::test {

class ManualClock final : public fw::Clock {
 public:
  explicit ManualClock(fw::Nanos t = 1'000'000'000) : t_(t) {}
  fw::Nanos now() override { return t_; }
  void sleep_until(fw::Nanos t) override {
    if (t > t_) t_ = t;
  }
  void advance(fw::Nanos dt) { t_ += dt; }

 private:
  fw::Nanos t_;
};

constexpr fw::Nanos kMs = 1'000'000;

}  // namespace fs::test
