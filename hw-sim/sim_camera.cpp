#include "hw-sim/sim_camera.hpp"

#include <algorithm>
#include <cmath>

namespace fs::sim {

SimCamera::SimCamera(fw::Clock& clock, SimMirror& mirror, SimLaser& laser, FrameRenderer& renderer,
                     FaultScript* faults, CameraTwinParams params)
    : clock_(clock), mirror_(mirror), laser_(laser), renderer_(renderer), faults_(faults), p_(params) {
  if (p_.buffers < 2) p_.buffers = 2;
  if (p_.frame_period <= 0) p_.frame_period = 1;
  slots_.resize(p_.buffers);
  for (auto& s : slots_) s.pixels.resize(static_cast<std::size_t>(renderer_.width()) * renderer_.height());
  delivered_.reserve(1 << 16);
}

void SimCamera::start(fw::Nanos now) {
  running_ = true;
  start_ = now + p_.phase;
  next_sensor_frame_ = 0;
  for (auto& s : slots_) s.queued = s.held = false;
}

void SimCamera::stop() noexcept {
  running_ = false;
  for (auto& s : slots_) s.queued = false;
}

std::uint32_t SimCamera::held() const {
  return static_cast<std::uint32_t>(
      std::count_if(slots_.begin(), slots_.end(), [](const Slot& s) { return s.held; }));
}

void SimCamera::advance_to(fw::Nanos now) {
  if (!running_) return;
  while (ready_time(next_sensor_frame_) <= now) {
    const std::uint64_t i = next_sensor_frame_++;
    const fw::Nanos t = exposure_start(i);
    if (faults_ && faults_->camera_timeout(t, sequence_)) continue;  // sensor produced nothing
    const std::uint32_t seq = sequence_++;
    if (faults_ && faults_->camera_drop(t, seq)) {
      ++dropped_;
      continue;
    }
    auto free =
        std::find_if(slots_.begin(), slots_.end(), [](const Slot& s) { return !s.queued && !s.held; });
    if (free == slots_.end()) {  // no buffer: the driver drops the frame
      ++dropped_;
      continue;
    }
    free->queued = true;
    free->sequence = seq;
    free->exposure_start = t;
    free->saturate = faults_ && faults_->camera_saturate(t, seq);
    free->order = order_++;
  }
}

fw::GrabResult SimCamera::grab(fw::Nanos deadline, fw::FrameView& out) {
  if (!running_) return fw::GrabResult::Error;
  fw::Nanos now = clock_.now();
  advance_to(now);
  auto oldest = [&]() {
    auto best = slots_.end();
    for (auto it = slots_.begin(); it != slots_.end(); ++it)
      if (it->queued && (best == slots_.end() || it->order < best->order)) best = it;
    return best;
  };
  auto slot = oldest();
  while (slot == slots_.end()) {
    const fw::Nanos next = ready_time(next_sensor_frame_);
    if (next > deadline) {
      if (deadline > now) clock_.sleep_until(deadline);
      return fw::GrabResult::Timeout;
    }
    clock_.sleep_until(next);
    now = std::max(clock_.now(), next);
    advance_to(now);
    slot = oldest();
  }
  Slot& s = *slot;
  s.queued = false;
  s.held = true;
  const fw::Nanos t0 = s.exposure_start, t1 = t0 + p_.exposure;
  FrameRecord rec;
  rec.sequence = s.sequence;
  rec.exposure_start = t0;
  rec.mirror_step = mirror_.position_at(t0 + p_.exposure / 2);
  rec.mirror_travel = std::abs(mirror_.position_at(t1) - mirror_.position_at(t0));
  rec.laser_fraction = laser_.on_fraction(t0, t1);
  rec.saturated = s.saturate;
  RenderRequest req;
  req.mirror_step = rec.mirror_step;
  req.laser_fraction = rec.laser_fraction;
  req.gain = s.saturate ? 30.0 : 1.0;
  req.seed = s.sequence;
  renderer_.render(req, s.pixels, renderer_.width());
  if (delivered_.size() < delivered_.capacity()) delivered_.push_back(rec);

  out.data = s.pixels.data();
  out.width = renderer_.width();
  out.height = renderer_.height();
  out.stride = renderer_.width();
  out.format = fw::PixelFormat::Mono8;
  out.sequence = s.sequence;
  out.timestamp = t0;
  out.buffer = static_cast<std::int32_t>(slot - slots_.begin());
  return fw::GrabResult::Ok;
}

void SimCamera::release(const fw::FrameView& frame) {
  if (frame.buffer < 0 || static_cast<std::size_t>(frame.buffer) >= slots_.size()) return;
  slots_[static_cast<std::size_t>(frame.buffer)].held = false;
}

const FrameRecord* SimCamera::find(std::uint32_t sequence) const {
  auto it = std::lower_bound(delivered_.begin(), delivered_.end(), sequence,
                             [](const FrameRecord& r, std::uint32_t s) { return r.sequence < s; });
  return it != delivered_.end() && it->sequence == sequence ? &*it : nullptr;
}

}  // namespace fs::sim
