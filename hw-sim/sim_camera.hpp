#pragma once
// Twin of a free-running V4L2 camera (implements fw::Camera).
//
// Frame i of the sensor is exposed over [start + i * period, + exposure] and is ready (dequeueable) at
// + exposure + readout. Like a V4L2 MMAP queue, there are `buffers` buffers: a frame finished while all of
// them are queued or held by the application is dropped (its sequence number is skipped: a gap). The
// timestamp of a frame is the start of its exposure, on the twins' clock. Frames are rendered lazily, when
// dequeued, for the mirror position at mid-exposure and the fraction of the exposure the laser emitted.
// grab() with deadline == now never blocks; with a later deadline it sleeps on the clock (virtual time
// advances). Faults: camera.timeout (the sensor stops producing frames), camera.drop (sequence gaps),
// camera.saturate (glare, gain x30).
#include <cstdint>
#include <vector>

#include "firmware/device/camera.hpp"
#include "hw-sim/frame_renderer.hpp"
#include "hw-sim/sim_faults.hpp"
#include "hw-sim/sim_laser.hpp"
#include "hw-sim/sim_mirror.hpp"

namespace fs::sim {

struct CameraTwinParams {
  fw::Nanos frame_period = 10'000'000;  // 100 fps
  fw::Nanos exposure = 2'000'000;
  fw::Nanos readout = 1'000'000;  // end of exposure -> frame dequeueable
  fw::Nanos phase = 0;            // first exposure starts at start(now) + phase
  std::uint32_t buffers = 4;
};

// What the twin knew about a delivered frame (ground truth for tests).
struct FrameRecord {
  std::uint32_t sequence = 0;
  fw::Nanos exposure_start = 0;
  double mirror_step = 0.0;    // at mid-exposure
  double mirror_travel = 0.0;  // |position(end) - position(start)| during the exposure
  double laser_fraction = 0.0;
  bool saturated = false;
};

class SimCamera final : public fw::Camera {
 public:
  SimCamera(fw::Clock& clock, SimMirror& mirror, SimLaser& laser, FrameRenderer& renderer,
            FaultScript* faults = nullptr, CameraTwinParams params = {});

  void start(fw::Nanos now) override;
  void stop() noexcept override;
  fw::GrabResult grab(fw::Nanos deadline, fw::FrameView& out) override;
  void release(const fw::FrameView& frame) override;
  std::uint32_t frames_dropped() const override { return dropped_; }

  const CameraTwinParams& params() const { return p_; }
  // Every frame handed to the application, in order (reserved up front; capped at 1 << 16 entries).
  const std::vector<FrameRecord>& delivered() const { return delivered_; }
  const FrameRecord* find(std::uint32_t sequence) const;
  std::uint32_t held() const;
  fw::Nanos exposure_start(std::uint64_t sensor_frame) const {
    return start_ + static_cast<fw::Nanos>(sensor_frame) * p_.frame_period;
  }

 private:
  struct Slot {
    std::vector<std::uint8_t> pixels;
    bool queued = false, held = false;
    std::uint32_t sequence = 0;
    fw::Nanos exposure_start = 0;
    bool saturate = false;
    std::uint64_t order = 0;
  };
  void advance_to(fw::Nanos now);
  fw::Nanos ready_time(std::uint64_t i) const { return exposure_start(i) + p_.exposure + p_.readout; }

  fw::Clock& clock_;
  SimMirror& mirror_;
  SimLaser& laser_;
  FrameRenderer& renderer_;
  FaultScript* faults_;
  CameraTwinParams p_;
  std::vector<Slot> slots_;
  std::vector<FrameRecord> delivered_;
  bool running_ = false;
  fw::Nanos start_ = 0;
  std::uint64_t next_sensor_frame_ = 0;  // first sensor frame not yet captured or dropped
  std::uint32_t sequence_ = 0;           // next V4L2 sequence number
  std::uint64_t order_ = 0;
  std::uint32_t dropped_ = 0;
};

}  // namespace fs::sim
