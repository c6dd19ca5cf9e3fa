// One device twin, one file: the drive's object dictionary, NMT, SDO server, state machine, motion profile
// and fault injection share the drive's state (see cia402_twin.hpp for what it implements).
#include "hw-sim/can/cia402_twin.hpp"

#include <fcntl.h>
#include <linux/can/error.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <limits>

namespace fs::sim {

using namespace cia402;
using fw::Nanos;

Cia402Twin::Cia402Twin(int fd, fw::Clock& clock, const Cia402TwinConfig& cfg)
    : fd_(fd), clock_(clock), cfg_(cfg) {
  int fl = ::fcntl(fd_, F_GETFL);
  if (fl >= 0) ::fcntl(fd_, F_SETFL, fl | O_NONBLOCK);
  pos_ = cfg_.start_position;
  target_ = static_cast<std::int32_t>(std::lround(pos_));
  target_obj_ = target_;
  reset_communication(clock_.now());
}

void Cia402Twin::reset_communication(Nanos now) {
  t_ = now;
  last_hb_ = now;
  last_tpdo_ = now;
  nmt_ = kStateBoot;
  can_frame f = make_frame(kHeartbeat + cfg_.node, 1);
  f.data[0] = kStateBoot;  // boot-up message
  send(f);
  nmt_ = kStatePreOperational;
}

std::uint16_t Cia402Twin::statusword() const {
  std::uint16_t sw = 0;
  switch (state_) {
    case DriveState::NotReadyToSwitchOn:
      sw = 0x00;
      break;
    case DriveState::SwitchOnDisabled:
      sw = 0x40;
      break;
    case DriveState::ReadyToSwitchOn:
      sw = 0x21 | kSwVoltageEnabled;
      break;
    case DriveState::SwitchedOn:
      sw = 0x23 | kSwVoltageEnabled;
      break;
    case DriveState::OperationEnabled:
      sw = 0x27 | kSwVoltageEnabled;
      break;
    case DriveState::QuickStopActive:
      sw = 0x07 | kSwVoltageEnabled;
      break;
    case DriveState::FaultReactionActive:
      sw = 0x0F;
      break;
    case DriveState::Fault:
      sw = 0x08;
      break;
  }
  sw |= kSwRemote;
  if (reached_) sw |= kSwTargetReached;
  if (mode_display_ == kModeHoming ? homing_attained_ : ack_) sw |= kSwSetPointAck;
  if (following_error_) sw |= kSwFollowingError;
  return sw;
}

void Cia402Twin::send(const can_frame& f) {
  if (no_response_ || bus_off_) return;
  ssize_t n;
  do n = ::write(fd_, &f, sizeof f);
  while (n < 0 && errno == EINTR);
  if (n == static_cast<ssize_t>(sizeof f)) ++stats_.frames_tx;  // else: queue full / peer gone: frame lost
}

void Cia402Twin::send_error(std::uint32_t err_id, std::uint8_t d1) {
  can_frame f = make_frame(CAN_ERR_FLAG | err_id, CAN_ERR_DLC);
  f.data[1] = d1;
  ssize_t n;
  do n = ::write(fd_, &f, sizeof f);
  while (n < 0 && errno == EINTR);
  if (n == static_cast<ssize_t>(sizeof f)) ++stats_.frames_tx;
}

void Cia402Twin::send_tpdo() {
  can_frame f = make_frame(kTpdo1 + cfg_.node, 6);
  const std::uint16_t sw = statusword();
  put_u16(f.data, sw);
  put_u32(f.data + 2, static_cast<std::uint32_t>(static_cast<std::int32_t>(std::lround(pos_))));
  send(f);
  ++stats_.tpdos;
  last_sw_sent_ = sw;
  last_tpdo_ = clock_.now();
}

void Cia402Twin::inject_drive_fault(std::uint16_t error_code) {
  error_code_ = error_code;
  state_ = DriveState::Fault;
  vel_ = 0.0;
  ack_ = false;
  homing_ = false;
  can_frame f = make_frame(kEmcy + cfg_.node, 8);
  put_u16(f.data, error_code);
  f.data[2] = 0x01;  // error register: generic error
  send(f);
  if (nmt_ == kStateOperational) send_tpdo();
}

void Cia402Twin::inject_error_passive(bool on) {
  send_error(CAN_ERR_CRTL, on ? (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE) : CAN_ERR_CRTL_ACTIVE);
}

void Cia402Twin::inject_bus_off(Nanos duration) {
  send_error(CAN_ERR_BUSOFF, 0);
  bus_off_ = true;
  bus_off_until_ = clock_.now() + duration;
}

void Cia402Twin::schedule(Nanos at, std::function<void(Cia402Twin&)> action) {
  schedule_.push_back({at, std::move(action), false});
}

void Cia402Twin::poll() {
  const Nanos now = clock_.now();
  for (auto& s : schedule_) {
    if (!s.done && now >= s.at) {
      s.done = true;
      s.action(*this);
    }
  }
  if (bus_off_ && now >= bus_off_until_) {
    bus_off_ = false;
    send_error(CAN_ERR_RESTARTED, 0);
  }
  can_frame f;
  for (;;) {
    ssize_t n = ::read(fd_, &f, sizeof f);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    ++stats_.frames_rx;
    if (n != static_cast<ssize_t>(sizeof f) || f.len > CAN_MAX_DLEN) {
      ++stats_.bad_frames;
      continue;
    }
    if (no_response_ || bus_off_) continue;  // the frame never reached the drive / the drive is mute
    advance(now);
    handle(f, now);
  }
  advance(now);
  if (!no_response_ && !bus_off_) {
    const Nanos hb = Nanos(hb_ms_) * 1'000'000;
    if (hb > 0 && now - last_hb_ >= hb) {
      last_hb_ = (now - last_hb_ < 2 * hb) ? last_hb_ + hb : now;
      if (!heartbeat_loss_) {
        can_frame h = make_frame(kHeartbeat + cfg_.node, 1);
        h.data[0] = nmt_;
        send(h);
        ++stats_.heartbeats;
      }
    }
    if (nmt_ == kStateOperational) {
      const Nanos ev = Nanos(tpdo_ms_) * 1'000'000;
      if (statusword() != last_sw_sent_ || (ev > 0 && now - last_tpdo_ >= ev)) send_tpdo();
    }
  }
  if (on_position_) on_position_(pos_, now);
}

void Cia402Twin::handle(const can_frame& f, Nanos now) {
  if (f.can_id & (CAN_ERR_FLAG | CAN_EFF_FLAG | CAN_RTR_FLAG)) return;
  const std::uint32_t id = f.can_id & CAN_SFF_MASK;
  if (id == kNmt) {
    if (f.len < 2 || (f.data[1] != 0 && f.data[1] != cfg_.node)) return;
    switch (f.data[0]) {
      case kNmtStart:
        nmt_ = kStateOperational;
        break;
      case kNmtStop:
        nmt_ = kStateStopped;
        break;
      case kNmtPreOp:
        nmt_ = kStatePreOperational;
        break;
      case kNmtResetNode:
        state_ = DriveState::SwitchOnDisabled;
        vel_ = 0.0;
        mode_ = mode_display_ = 0;
        hb_ms_ = tpdo_ms_ = 0;
        ack_ = homing_ = homing_attained_ = following_error_ = false;
        error_code_ = 0;
        reset_communication(now);
        break;
      case kNmtResetComm:
        hb_ms_ = tpdo_ms_ = 0;
        reset_communication(now);
        break;
      default:
        ++stats_.bad_frames;
        break;
    }
    return;
  }
  if (id == kSdoRx + cfg_.node) {
    if (nmt_ != kStateStopped) handle_sdo(f, now);
    return;
  }
  if (id == kRpdo1 + cfg_.node) {
    if (nmt_ != kStateOperational) return;
    if (f.len < 6) {
      ++stats_.bad_frames;
      return;
    }
    ++stats_.rpdos;
    target_obj_ = static_cast<std::int32_t>(get_u32(f.data + 2));
    handle_controlword(get_u16(f.data), now);
    if (statusword() != last_sw_sent_) send_tpdo();  // handshake edges are reported at once
  }
}

void Cia402Twin::handle_sdo(const can_frame& f, Nanos now) {
  ++stats_.sdo_requests;
  const std::uint32_t resp = kSdoTx + cfg_.node;
  if (f.len < 8) {
    ++stats_.bad_frames;
    return;
  }
  const std::uint8_t cmd = f.data[0];
  const std::uint16_t index = get_u16(f.data + 1);
  const std::uint8_t sub = f.data[3];
  std::uint32_t abort = 0;
  const int ccs = cmd >> 5;
  if (ccs == 1) {  // download (write)
    if (!(cmd & 0x02) || !(cmd & 0x01)) {
      abort = kAbortCommand;  // only expedited transfers with size indicated
    } else {
      const int size = 4 - ((cmd >> 2) & 3);
      std::uint32_t v = get_u32(f.data + 4);
      if (size < 4) v &= (1u << (8 * size)) - 1;
      if (sdo_write(index, sub, v, size, abort, now)) {
        can_frame r = make_frame(resp, 8);
        r.data[0] = kSdoWriteResp;
        put_u16(r.data + 1, index);
        r.data[3] = sub;
        send(r);
        if (nmt_ == kStateOperational && statusword() != last_sw_sent_) send_tpdo();
        return;
      }
    }
  } else if (ccs == 2) {  // upload (read)
    std::uint32_t v = 0;
    int size = 0;
    if (sdo_read(index, sub, v, size, abort)) {
      can_frame r = make_frame(resp, 8);
      r.data[0] = static_cast<std::uint8_t>(0x43 | ((4 - size) << 2));
      put_u16(r.data + 1, index);
      r.data[3] = sub;
      put_u32(r.data + 4, v);
      send(r);
      return;
    }
  } else {
    abort = kAbortCommand;
  }
  ++stats_.sdo_aborts;
  send(sdo_abort(resp, index, sub, abort));
}

bool Cia402Twin::sdo_write(std::uint16_t index, std::uint8_t sub, std::uint32_t v, int size,
                           std::uint32_t& abort, Nanos now) {
  auto expect = [&](int want_sub, int want_size) {
    if (sub != want_sub) {
      abort = kAbortNoObject;
      return false;
    }
    if (size != want_size) {
      abort = kAbortLength;
      return false;
    }
    return true;
  };
  switch (index) {
    case kHeartbeatProducer:
      if (!expect(0, 2)) return false;
      hb_ms_ = static_cast<std::uint16_t>(v);
      last_hb_ = now;
      return true;
    case kTpdo1Comm:
      if (!expect(5, 2)) return false;
      tpdo_ms_ = static_cast<std::uint16_t>(v);
      return true;
    case kControlword:
      if (!expect(0, 2)) return false;
      handle_controlword(static_cast<std::uint16_t>(v), now);
      return true;
    case kModesOfOperation: {
      if (!expect(0, 1)) return false;
      const auto m = static_cast<std::int8_t>(v);
      if (m != kModeProfilePosition && m != kModeHoming) {
        abort = kAbortRange;
        return false;
      }
      mode_ = mode_display_ = m;
      ack_ = homing_ = homing_attained_ = false;
      return true;
    }
    case kTargetPosition:
      if (!expect(0, 4)) return false;
      target_obj_ = static_cast<std::int32_t>(v);
      return true;
    case kHomeOffset:
      if (!expect(0, 4)) return false;
      home_offset_ = static_cast<std::int32_t>(v);
      return true;
    case kProfileVelocity:
    case kProfileAcceleration:
    case kProfileDeceleration:
      if (!expect(0, 4)) return false;
      if (v == 0 || (index == kProfileVelocity && v > cfg_.max_velocity)) {
        abort = kAbortRange;
        return false;
      }
      (index == kProfileVelocity ? prof_vel_ : index == kProfileAcceleration ? prof_acc_ : prof_dec_) = v;
      return true;
    case kHomingMethod: {
      if (!expect(0, 1)) return false;
      const auto m = static_cast<std::int8_t>(v);
      if (m != 35 && m != kHomingOnCurrentPosition) {
        abort = kAbortRange;
        return false;
      }
      homing_method_ = m;
      return true;
    }
    case kErrorCode:
    case kStatusword:
    case kModesDisplay:
    case kPositionActual:
      abort = sub == 0 ? kAbortReadOnly : kAbortNoObject;
      return false;
    default:
      abort = kAbortNoObject;
      return false;
  }
}

bool Cia402Twin::sdo_read(std::uint16_t index, std::uint8_t sub, std::uint32_t& v, int& size,
                          std::uint32_t& abort) const {
  if (index == kTpdo1Comm) {
    if (sub != 5) {
      abort = kAbortNoObject;
      return false;
    }
    v = tpdo_ms_;
    size = 2;
    return true;
  }
  if (sub != 0) {
    abort = kAbortNoObject;
    return false;
  }
  switch (index) {
    case kHeartbeatProducer:
      v = hb_ms_;
      size = 2;
      return true;
    case 0x1000:
      v = 0x00020192;
      size = 4;
      return true;  // device type: CiA 402 (0x0192), servo drive (0x0002)
    case kErrorCode:
      v = error_code_;
      size = 2;
      return true;
    case kControlword:
      v = cw_;
      size = 2;
      return true;
    case kStatusword:
      v = statusword();
      size = 2;
      return true;
    case kModesOfOperation:
      v = std::uint8_t(mode_);
      size = 1;
      return true;
    case kModesDisplay:
      v = std::uint8_t(mode_display_);
      size = 1;
      return true;
    case kPositionActual:
      v = std::uint32_t(std::int32_t(std::lround(pos_)));
      size = 4;
      return true;
    case kTargetPosition:
      v = std::uint32_t(target_obj_);
      size = 4;
      return true;
    case kHomeOffset:
      v = std::uint32_t(home_offset_);
      size = 4;
      return true;
    case kProfileVelocity:
      v = prof_vel_;
      size = 4;
      return true;
    case kProfileAcceleration:
      v = prof_acc_;
      size = 4;
      return true;
    case kProfileDeceleration:
      v = prof_dec_;
      size = 4;
      return true;
    case kHomingMethod:
      v = std::uint8_t(homing_method_);
      size = 1;
      return true;
    default:
      abort = kAbortNoObject;
      return false;
  }
}

void Cia402Twin::handle_controlword(std::uint16_t cw, Nanos now) {
  const std::uint16_t prev = cw_;
  cw_ = cw;
  const std::uint16_t rising = cw & ~prev;
  const bool disable_voltage = !(cw & 0x02);
  const bool quick_stop = (cw & 0x06) == 0x02;
  const std::uint16_t cmd = cw & 0x8F;
  const DriveState before = state_;
  switch (state_) {
    case DriveState::Fault:
    case DriveState::FaultReactionActive:
      if (rising & kCwFaultReset) {
        state_ = DriveState::SwitchOnDisabled;
        error_code_ = 0;
        following_error_ = false;
        can_frame f = make_frame(kEmcy + cfg_.node, 8);  // EMCY "error reset / no error"
        send(f);
      }
      break;
    case DriveState::NotReadyToSwitchOn:
      break;
    case DriveState::SwitchOnDisabled:
      if ((cw & 0x87) == 0x06) state_ = DriveState::ReadyToSwitchOn;
      break;
    case DriveState::ReadyToSwitchOn:
      if (disable_voltage || quick_stop)
        state_ = DriveState::SwitchOnDisabled;
      else if (cmd == 0x07)
        state_ = DriveState::SwitchedOn;
      else if (cmd == 0x0F)
        state_ = DriveState::OperationEnabled;
      break;
    case DriveState::SwitchedOn:
      if (disable_voltage || quick_stop)
        state_ = DriveState::SwitchOnDisabled;
      else if (cmd == 0x06)
        state_ = DriveState::ReadyToSwitchOn;
      else if (cmd == 0x0F)
        state_ = DriveState::OperationEnabled;
      break;
    case DriveState::OperationEnabled:
      if (disable_voltage)
        state_ = DriveState::SwitchOnDisabled;
      else if (quick_stop)
        state_ = DriveState::QuickStopActive;
      else if (cmd == 0x07)
        state_ = DriveState::SwitchedOn;
      else if (cmd == 0x06)
        state_ = DriveState::ReadyToSwitchOn;
      break;
    case DriveState::QuickStopActive:
      if (disable_voltage) state_ = DriveState::SwitchOnDisabled;
      break;
  }
  if (state_ == DriveState::OperationEnabled && before != DriveState::OperationEnabled) {
    target_ = static_cast<std::int32_t>(std::lround(pos_));  // hold the current position
    reached_ = true;
    ack_ = false;
    following_error_ = false;
  }
  if (state_ != DriveState::OperationEnabled) {
    if (state_ != DriveState::QuickStopActive) vel_ = 0.0;
    ack_ = false;
    homing_ = false;
    return;
  }
  if (before != DriveState::OperationEnabled) return;  // set-point bits count from the next controlword on
  halted_ = cw & kCwHalt;
  if (mode_ == kModeProfilePosition) {
    if (rising & kCwNewSetPoint) {
      // A relative set-point adds to the last target in 64 bits and saturates at the int32 range (any
      // target object the master sends is valid; the sum must not overflow).
      const std::int32_t t =
          (cw & kCwRelative)
              ? static_cast<std::int32_t>(std::clamp<std::int64_t>(std::int64_t{target_} + target_obj_,
                                                                   std::numeric_limits<std::int32_t>::min(),
                                                                   std::numeric_limits<std::int32_t>::max()))
              : target_obj_;
      target_ = t;
      ack_ = true;
      ++stats_.setpoints;
      reached_ = std::abs(pos_ - t) < 1e-9 && vel_ == 0.0;
      following_error_ = false;
    } else if (!(cw & kCwNewSetPoint)) {
      ack_ = false;
    }
  } else if (mode_ == kModeHoming) {
    if (rising & kCwNewSetPoint) {
      homing_ = true;
      homing_attained_ = false;
      reached_ = false;
      homing_done_ = now + cfg_.homing_time;
    } else if (!(cw & kCwNewSetPoint) && homing_) {
      homing_ = false;  // homing interrupted
      reached_ = true;
    }
  }
}

void Cia402Twin::advance(Nanos now) {
  if (now <= t_) return;
  if (state_ != DriveState::OperationEnabled && state_ != DriveState::QuickStopActive) {
    vel_ = 0.0;
    t_ = now;
    return;
  }
  if (homing_ && now >= homing_done_) {
    pos_ = home_offset_;  // method 35/37: the current position becomes the home position
    target_ = home_offset_;
    vel_ = 0.0;
    homing_ = false;
    homing_attained_ = true;
    reached_ = true;
  }
  const double dt = static_cast<double>(cfg_.motion_step) * 1e-9;
  const double vmax = std::min<double>(prof_vel_, cfg_.max_velocity);
  const double acc = prof_acc_, dec = prof_dec_;
  if (now - t_ > 10'000'000'000LL) t_ = now - 10'000'000'000LL;  // bound the work after a long gap
  while (t_ < now) {
    t_ = std::min(now, t_ + cfg_.motion_step);
    const bool stopping = state_ == DriveState::QuickStopActive || halted_ || mode_ != kModeProfilePosition;
    if (stopping) {
      const double dv = std::min(std::abs(vel_), dec * dt);
      vel_ -= std::copysign(dv, vel_);
      pos_ += vel_ * dt;
      if (on_position_ && vel_ != 0.0) on_position_(pos_, t_);
      if (vel_ == 0.0 && state_ == DriveState::QuickStopActive) state_ = DriveState::SwitchOnDisabled;
      if (state_ != DriveState::OperationEnabled && state_ != DriveState::QuickStopActive) break;
      continue;
    }
    if (stalled_) {
      vel_ = 0.0;
      if (cfg_.following_limit > 0 && std::abs(target_ - pos_) > cfg_.following_limit)
        following_error_ = true;
      continue;
    }
    const double rem = target_ - pos_;
    if (rem == 0.0 && vel_ == 0.0) {
      reached_ = true;
      continue;
    }
    reached_ = false;
    const double dir = rem > 0 ? 1.0 : -1.0;
    const double vt = vel_ * dir;
    double vnew;
    if (vt < 0) {
      vnew = vel_ + dir * std::min(dec * dt, -vt);
    } else {
      vnew = dir * std::min({vmax, vt + acc * dt, std::sqrt(2.0 * dec * std::abs(rem))});
    }
    pos_ += vnew * dt;
    vel_ = vnew;
    if ((target_ - pos_) * dir <= 0 && vt >= 0) {
      pos_ = target_;
      vel_ = 0.0;
      reached_ = true;
    }
    // The mirror follows the motor along its trajectory (each sub-step at its own time), not only at the
    // polls: a poll long after the landing must not look like a jump of the motor at the poll's time.
    if (on_position_) on_position_(pos_, t_);
  }
}

}  // namespace fs::sim
