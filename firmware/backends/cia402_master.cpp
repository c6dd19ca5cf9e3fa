#include "firmware/backends/cia402_master.hpp"

#include <linux/can/error.h>

#include <cstdlib>

namespace fs::fw {

using namespace cia402;

Cia402Master::Cia402Master(CanPort& port, const Cia402Config& cfg) : port_(port), cfg_(cfg) {}

void Cia402Master::enable(Nanos now) {
  if (phase_ == Phase::Configuring || phase_ == Phase::Enabling || phase_ == Phase::Ready ||
      phase_ == Phase::HomingConfig || phase_ == Phase::Homing || phase_ == Phase::HomingRestore)
    return;
  if (fault_ != GalvoFault::None) return;  // reset_fault() first
  start_configuration(now);
}

void Cia402Master::start_configuration(Nanos now) {
  sdo_head_ = sdo_tail_ = 0;
  sdo_in_flight_ = false;
  sp_ = SetPoint::Idle;
  statusword_seen_ = false;
  heartbeat_expected_ = false;
  if (!diag_.bus_off) {
    port_.send(nmt(kNmtStart, cfg_.node));
    ++diag_.frames_tx;
  }
  queue_sdo({kHeartbeatProducer, 0, 2, false, cfg_.heartbeat_ms});
  queue_sdo({kTpdo1Comm, 5, 2, false, cfg_.tpdo_event_ms});
  queue_sdo({kModesOfOperation, 0, 1, false, std::uint8_t(kModeProfilePosition)});
  queue_sdo({kProfileVelocity, 0, 4, false, cfg_.velocity});
  queue_sdo({kProfileAcceleration, 0, 4, false, cfg_.acceleration});
  queue_sdo({kProfileDeceleration, 0, 4, false, cfg_.acceleration});
  queue_sdo({kModesDisplay, 0, 1, true, std::uint8_t(kModeProfilePosition)});
  queue_sdo({kStatusword, 0, 2, true, 0});
  phase_ = Phase::Configuring;
  phase_start_ = now;
  send_sdo(now);
}

void Cia402Master::queue_sdo(const SdoOp& op) {
  if (sdo_tail_ - sdo_head_ >= sdo_.size()) return;  // cannot happen: at most 8 ops are queued at once
  sdo_[sdo_tail_++ % sdo_.size()] = op;
}

void Cia402Master::send_sdo(Nanos now) {
  if (sdo_in_flight_ || sdo_head_ == sdo_tail_ || diag_.bus_off) return;
  const SdoOp& op = sdo_[sdo_head_ % sdo_.size()];
  port_.send(op.read ? sdo_read(cfg_.node, op.index, op.sub)
                     : sdo_write(cfg_.node, op.index, op.sub, op.value, op.size));
  ++diag_.frames_tx;
  sdo_in_flight_ = true;
  sdo_attempts_ = 1;
  sdo_sent_ = now;
}

void Cia402Master::send_rpdo() {
  if (diag_.bus_off) return;
  can_frame f = make_frame(kRpdo1 + cfg_.node, 6);
  put_u16(f.data, cw_);
  put_u32(f.data + 2, static_cast<std::uint32_t>(target_));
  port_.send(f);
  ++diag_.frames_tx;
}

void Cia402Master::set_cw(std::uint16_t cw) {
  cw_ = cw;
  send_rpdo();
}

void Cia402Master::fault(GalvoFault f, Nanos now) {
  if (fault_ != GalvoFault::None && f != GalvoFault::BusOff) return;  // the first cause is reported
  fault_ = f;
  diag_.fault_time = now;
  phase_ = Phase::Faulted;
  sp_ = SetPoint::Idle;
  pending_move_ = false;
  sdo_head_ = sdo_tail_ = 0;
  sdo_in_flight_ = false;
  if (f == GalvoFault::Stall || f == GalvoFault::HomeNotFound)
    set_cw(kCwSwitchOn);  // disable operation: stop
}

void Cia402Master::move_to(std::int32_t step, Nanos now) {
  commanded_ = step;
  if (phase_ == Phase::Ready && sp_ == SetPoint::Idle) {
    issue_setpoint(step, now);
  } else {
    pending_move_ = true;
    pending_target_ = step;
  }
}

void Cia402Master::issue_setpoint(std::int32_t target, Nanos now) {
  target_ = target;
  pending_move_ = false;
  sp_ = SetPoint::WaitAck;
  cw_sent_ = now;
  set_cw(kCwEnableOperation | kCwNewSetPoint | kCwChangeImmediately);
}

void Cia402Master::start_homing(Nanos now) {
  if (phase_ != Phase::Ready) return;
  pending_move_ = false;
  queue_sdo({kModesOfOperation, 0, 1, false, std::uint8_t(kModeHoming)});
  queue_sdo({kHomingMethod, 0, 1, false, std::uint8_t(kHomingOnCurrentPosition)});
  phase_ = Phase::HomingConfig;
  phase_start_ = now;
  homed_ = false;
  send_sdo(now);
}

void Cia402Master::reset_fault(Nanos now) {
  switch (fault_) {
    case GalvoFault::None:
      return;
    case GalvoFault::BusOff:
      if (diag_.bus_off) {
        recover_after_restart_ = true;  // re-initialise once the controller is back on the bus
        return;
      }
      fault_ = GalvoFault::None;
      start_configuration(now);
      return;
    case GalvoFault::CommLost:
      fault_ = GalvoFault::None;
      start_configuration(now);
      return;
    default: {
      fault_ = GalvoFault::None;
      DriveState s = decode_state(diag_.statusword);
      if (s == DriveState::Fault || s == DriveState::FaultReactionActive) {
        set_cw(kCwDisableVoltage);
        set_cw(kCwFaultReset);  // rising edge of bit 7
        phase_ = Phase::FaultReset;
        phase_start_ = now;
        cw_sent_ = now;
      } else {
        start_configuration(now);
      }
      return;
    }
  }
}

void Cia402Master::disable() noexcept {
  cw_ = kCwDisableVoltage;
  send_rpdo();
  port_.flush();
  if (phase_ != Phase::Faulted) phase_ = Phase::Disabled;
  sp_ = SetPoint::Idle;
  pending_move_ = false;
  sdo_head_ = sdo_tail_ = 0;
  sdo_in_flight_ = false;
}

bool Cia402Master::heartbeat_armed() const {
  return heartbeat_expected_ && cfg_.heartbeat_ms > 0 && !diag_.bus_off && phase_ != Phase::Faulted &&
         phase_ != Phase::Idle && phase_ != Phase::Disabled;
}

void Cia402Master::handle_error_frame(const can_frame& f, Nanos now) {
  ++diag_.error_frames;
  const canid_t id = f.can_id & CAN_ERR_MASK;
  if (id & CAN_ERR_BUSOFF) {
    diag_.bus_off = true;
    port_.drop_queue();
    fault(GalvoFault::BusOff, now);
  }
  if ((id & CAN_ERR_CRTL) && f.len >= 2) {
    if (f.data[1] & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) diag_.error_passive = true;
    if (f.data[1] & CAN_ERR_CRTL_ACTIVE) diag_.error_passive = false;
  }
  if (id & CAN_ERR_RESTARTED) {
    diag_.bus_off = false;
    diag_.error_passive = false;
    if (recover_after_restart_) {
      recover_after_restart_ = false;
      fault_ = GalvoFault::None;
      start_configuration(now);
    }
  }
}

void Cia402Master::handle_sdo(const can_frame& f, Nanos now) {
  if (!sdo_in_flight_ || f.len < 8) return;
  const SdoOp& op = sdo_[sdo_head_ % sdo_.size()];
  if (get_u16(f.data + 1) != op.index || f.data[3] != op.sub) return;  // stale answer to an earlier attempt
  const std::uint8_t cmd = f.data[0];
  if (cmd == kSdoAbort) {
    diag_.sdo_abort = get_u32(f.data + 4);
    fault(GalvoFault::DriveFault, now);
    return;
  }
  if (op.read) {
    if ((cmd & 0xE0) != kSdoReadResp || !(cmd & 0x02)) return;  // not an expedited upload response
    std::uint32_t v = get_u32(f.data + 4);
    if (cmd & 0x01) {
      int n = 4 - ((cmd >> 2) & 3);
      if (n < 4) v &= (1u << (8 * n)) - 1;
    }
    if (op.index == kModesDisplay && static_cast<std::int8_t>(v) != static_cast<std::int8_t>(op.value)) {
      fault(GalvoFault::DriveFault, now);  // the drive did not take the mode
      return;
    }
    if (op.index == kStatusword) {
      diag_.statusword = static_cast<std::uint16_t>(v);
      diag_.drive_state = decode_state(diag_.statusword);
      statusword_seen_ = true;
    }
  } else {
    if (cmd != kSdoWriteResp) return;
    if (op.index == kHeartbeatProducer) {
      heartbeat_expected_ = true;
      diag_.last_heartbeat = now;
    }
  }
  ++sdo_head_;
  sdo_in_flight_ = false;
  send_sdo(now);
}

void Cia402Master::handle(const can_frame& f, Nanos now) {
  if (f.can_id & CAN_ERR_FLAG) return handle_error_frame(f, now);
  if (f.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG)) return;
  const std::uint32_t id = f.can_id & CAN_SFF_MASK;
  const std::uint8_t n = cfg_.node;
  if (id == kHeartbeat + n && f.len >= 1) {
    const std::uint8_t st = f.data[0] & 0x7F;
    diag_.nmt_state = st;
    diag_.last_heartbeat = now;
    if (phase_ == Phase::Configuring) {
      if (st == kStateBoot || st == kStatePreOperational) {
        port_.send(nmt(kNmtStart, n));
        ++diag_.frames_tx;
      }
    } else if (st != kStateOperational && phase_ != Phase::Idle && phase_ != Phase::Faulted &&
               phase_ != Phase::Disabled) {
      if (st == kStateBoot) homed_ = false;  // the drive rebooted: its position reference is gone
      fault(GalvoFault::CommLost, now);
    }
  } else if (id == kTpdo1 + n && f.len >= 6) {
    const std::uint16_t sw = get_u16(f.data);
    position_ = static_cast<std::int32_t>(get_u32(f.data + 2));
    diag_.statusword = sw;
    diag_.drive_state = decode_state(sw);
    statusword_seen_ = true;
    const DriveState s = diag_.drive_state;
    if ((s == DriveState::Fault || s == DriveState::FaultReactionActive) && phase_ != Phase::FaultReset) {
      fault(GalvoFault::DriveFault, now);
      return;
    }
    if (phase_ == Phase::Ready) {
      if (s != DriveState::OperationEnabled) {
        fault(GalvoFault::DriveFault, now);  // dropped out of operation enabled on its own
        return;
      }
      if (sw & kSwFollowingError) {
        fault(GalvoFault::Stall, now);
        return;
      }
      if (sp_ == SetPoint::WaitAck && (sw & kSwSetPointAck)) {
        ++diag_.setpoints_acknowledged;
        sp_ = SetPoint::WaitAckClear;
        set_cw(kCwEnableOperation | kCwChangeImmediately);
      } else if (sp_ == SetPoint::WaitAckClear && !(sw & kSwSetPointAck)) {
        sp_ = SetPoint::Idle;
        if (pending_move_) issue_setpoint(pending_target_, now);
      }
    }
  } else if (id == kSdoTx + n) {
    handle_sdo(f, now);
  } else if (id == kEmcy + n && f.len >= 2) {
    diag_.emcy_code = get_u16(f.data);
    if (diag_.emcy_code != 0 && phase_ != Phase::FaultReset) fault(GalvoFault::DriveFault, now);
  }
}

void Cia402Master::step(Nanos now) {
  if (diag_.bus_off) return;
  if (sdo_in_flight_ && now - sdo_sent_ > cfg_.sdo_timeout) {
    if (sdo_attempts_ > cfg_.sdo_retries) {
      fault(GalvoFault::CommLost, now);
      return;
    }
    const SdoOp& op = sdo_[sdo_head_ % sdo_.size()];
    port_.send(op.read ? sdo_read(cfg_.node, op.index, op.sub)
                       : sdo_write(cfg_.node, op.index, op.sub, op.value, op.size));
    ++diag_.frames_tx;
    ++sdo_attempts_;
    sdo_sent_ = now;
  }
  send_sdo(now);
  if (heartbeat_armed() && now - diag_.last_heartbeat > 2 * Nanos(cfg_.heartbeat_ms) * 1'000'000) {
    fault(GalvoFault::CommLost, now);
    return;
  }
  const bool sdo_idle = !sdo_in_flight_ && sdo_head_ == sdo_tail_;
  const std::uint16_t sw = diag_.statusword;
  switch (phase_) {
    case Phase::Configuring:
      if (sdo_idle) {
        phase_ = Phase::Enabling;
        phase_start_ = now;
        cw_sent_ = now;
        cw_ = 0xFFFF;  // force the first controlword out
      }
      [[fallthrough]];
    case Phase::Enabling: {
      if (phase_ != Phase::Enabling) break;
      if (now - phase_start_ > cfg_.state_timeout) {
        fault(statusword_seen_ ? GalvoFault::DriveFault : GalvoFault::CommLost, now);
        break;
      }
      std::uint16_t want = cw_;
      switch (diag_.drive_state) {
        case DriveState::SwitchOnDisabled:
          want = kCwShutdown;
          break;
        case DriveState::ReadyToSwitchOn:
          want = kCwSwitchOn;
          break;
        case DriveState::SwitchedOn:
          want = kCwEnableOperation;
          break;
        case DriveState::QuickStopActive:
          want = kCwDisableVoltage;
          break;
        case DriveState::OperationEnabled:
          phase_ = Phase::Ready;
          target_ = position_;
          if (cw_ != kCwEnableOperation) set_cw(kCwEnableOperation);
          if (pending_move_) issue_setpoint(pending_target_, now);
          break;
        default:
          want = kCwShutdown;
          break;
      }
      if (phase_ == Phase::Enabling && (want != cw_ || now - cw_sent_ > 100'000'000)) {
        target_ = position_;  // never let an old target start a motion on enable
        cw_sent_ = now;
        set_cw(want);
      }
      break;
    }
    case Phase::Ready:
      if (sp_ != SetPoint::Idle && now - cw_sent_ > cfg_.state_timeout) fault(GalvoFault::CommLost, now);
      break;
    case Phase::HomingConfig:
      if (sdo_idle) {
        phase_ = Phase::Homing;
        phase_start_ = now;
        set_cw(kCwEnableOperation | kCwNewSetPoint);  // homing operation start
      }
      break;
    case Phase::Homing:
      if (sw & kSwFollowingError) {
        fault(GalvoFault::HomeNotFound, now);
      } else if ((sw & kSwSetPointAck) && (sw & kSwTargetReached)) {
        set_cw(kCwEnableOperation);
        queue_sdo({kModesOfOperation, 0, 1, false, std::uint8_t(kModeProfilePosition)});
        queue_sdo({kModesDisplay, 0, 1, true, std::uint8_t(kModeProfilePosition)});
        phase_ = Phase::HomingRestore;
        send_sdo(now);
      } else if (now - phase_start_ > cfg_.state_timeout) {
        fault(GalvoFault::HomeNotFound, now);
      }
      break;
    case Phase::HomingRestore:
      if (sdo_idle) {
        homed_ = true;
        phase_ = Phase::Ready;
        target_ = position_;
        commanded_ = position_;
        if (pending_move_) issue_setpoint(pending_target_, now);
      }
      break;
    case Phase::FaultReset: {
      const DriveState s = diag_.drive_state;
      if (s != DriveState::Fault && s != DriveState::FaultReactionActive) {
        start_configuration(now);
      } else if (now - phase_start_ > cfg_.state_timeout) {
        fault(GalvoFault::DriveFault, now);
      }
      break;
    }
    default:
      break;
  }
}

GalvoStatus Cia402Master::poll(Nanos now) {
  can_frame f;
  Nanos kts = 0;
  for (int i = 0; i < 256 && port_.recv(f, kts); ++i) {
    ++diag_.frames_rx;
    if (kts) diag_.last_rx_kernel_ts = kts;
    handle(f, now);
  }
  step(now);
  port_.flush();

  GalvoStatus st;
  const std::uint16_t sw = diag_.statusword;
  st.commanded_step = commanded_;
  st.measured_step = position_;
  st.homed = homed_;
  st.fault = fault_;
  const bool homing =
      phase_ == Phase::HomingConfig || phase_ == Phase::Homing || phase_ == Phase::HomingRestore;
  st.enabled = fault_ == GalvoFault::None && (phase_ == Phase::Ready || homing) &&
               diag_.drive_state == DriveState::OperationEnabled;
  st.moving = homing || (phase_ == Phase::Ready &&
                         (sp_ != SetPoint::Idle || pending_move_ || !(sw & kSwTargetReached)));
  // In 64 bits: the drive may report any int32 position, however far from the target.
  st.in_position = phase_ == Phase::Ready && sp_ == SetPoint::Idle && !pending_move_ &&
                   (sw & kSwTargetReached) &&
                   std::abs(static_cast<std::int64_t>(position_) - target_) <= cfg_.position_window;
  return st;
}

}  // namespace fs::fw
