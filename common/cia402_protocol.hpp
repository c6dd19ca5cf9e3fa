#pragma once
// CANopen (CiA 301) and CiA 402 constants and frame helpers shared by the master (firmware/backends/) and the
// drive twin (hw-sim/can/). Header only; works on plain struct can_frame.
//
// PDO mapping the master relies on (the twin implements it; a real drive is configured to it):
//   RPDO1 0x200+node: controlword 6040h (u16) + target position 607Ah (i32)
//   TPDO1 0x180+node: statusword 6041h (u16) + position actual value 6064h (i32); sent on change of the
//                      statusword and every 1800h:05 ms (event timer) while operational
#include <linux/can.h>

#include <cstdint>
#include <cstring>

namespace fs::cia402 {

// COB-ID function codes (11-bit identifiers, node id added).
constexpr std::uint32_t kNmt = 0x000;
constexpr std::uint32_t kEmcy = 0x080;
constexpr std::uint32_t kTpdo1 = 0x180;
constexpr std::uint32_t kRpdo1 = 0x200;
constexpr std::uint32_t kSdoTx = 0x580;  // server -> client (responses)
constexpr std::uint32_t kSdoRx = 0x600;  // client -> server (requests)
constexpr std::uint32_t kHeartbeat = 0x700;

// NMT commands and states.
constexpr std::uint8_t kNmtStart = 0x01, kNmtStop = 0x02, kNmtPreOp = 0x80, kNmtResetNode = 0x81,
                       kNmtResetComm = 0x82;
constexpr std::uint8_t kStateBoot = 0x00, kStateStopped = 0x04, kStateOperational = 0x05,
                       kStatePreOperational = 0x7F;

// Objects.
constexpr std::uint16_t kHeartbeatProducer = 0x1017;    // u16 ms
constexpr std::uint16_t kTpdo1Comm = 0x1800;            // sub 5: event timer u16 ms
constexpr std::uint16_t kErrorCode = 0x603F;            // u16
constexpr std::uint16_t kControlword = 0x6040;          // u16
constexpr std::uint16_t kStatusword = 0x6041;           // u16
constexpr std::uint16_t kModesOfOperation = 0x6060;     // i8
constexpr std::uint16_t kModesDisplay = 0x6061;         // i8
constexpr std::uint16_t kPositionActual = 0x6064;       // i32
constexpr std::uint16_t kTargetPosition = 0x607A;       // i32
constexpr std::uint16_t kHomeOffset = 0x607C;           // i32
constexpr std::uint16_t kProfileVelocity = 0x6081;      // u32
constexpr std::uint16_t kProfileAcceleration = 0x6083;  // u32
constexpr std::uint16_t kProfileDeceleration = 0x6084;  // u32
constexpr std::uint16_t kHomingMethod = 0x6098;         // i8

constexpr std::int8_t kModeProfilePosition = 1;
constexpr std::int8_t kModeHoming = 6;
constexpr std::int8_t kHomingOnCurrentPosition = 37;

// SDO command specifiers (expedited).
constexpr std::uint8_t kSdoWriteReq = 0x20;  // | (4-n)<<2 | 0x03
constexpr std::uint8_t kSdoWriteResp = 0x60;
constexpr std::uint8_t kSdoReadReq = 0x40;
constexpr std::uint8_t kSdoReadResp = 0x40;  // 0x43 / 0x47 / 0x4B / 0x4F
constexpr std::uint8_t kSdoAbort = 0x80;
constexpr std::uint32_t kAbortNoObject = 0x06020000;
constexpr std::uint32_t kAbortReadOnly = 0x06010002;
constexpr std::uint32_t kAbortLength = 0x06070010;
constexpr std::uint32_t kAbortCommand = 0x05040001;
constexpr std::uint32_t kAbortRange = 0x06090030;

// Controlword bits / commands.
constexpr std::uint16_t kCwShutdown = 0x0006;
constexpr std::uint16_t kCwSwitchOn = 0x0007;
constexpr std::uint16_t kCwEnableOperation = 0x000F;
constexpr std::uint16_t kCwDisableVoltage = 0x0000;
constexpr std::uint16_t kCwNewSetPoint = 1u
                                         << 4;  // profile position; = homing operation start in homing mode
constexpr std::uint16_t kCwChangeImmediately = 1u << 5;
constexpr std::uint16_t kCwRelative = 1u << 6;
constexpr std::uint16_t kCwFaultReset = 1u << 7;
constexpr std::uint16_t kCwHalt = 1u << 8;

// Statusword bits.
constexpr std::uint16_t kSwReadyToSwitchOn = 1u << 0;
constexpr std::uint16_t kSwSwitchedOn = 1u << 1;
constexpr std::uint16_t kSwOperationEnabled = 1u << 2;
constexpr std::uint16_t kSwFault = 1u << 3;
constexpr std::uint16_t kSwVoltageEnabled = 1u << 4;
constexpr std::uint16_t kSwQuickStop = 1u << 5;
constexpr std::uint16_t kSwSwitchOnDisabled = 1u << 6;
constexpr std::uint16_t kSwWarning = 1u << 7;
constexpr std::uint16_t kSwRemote = 1u << 9;
constexpr std::uint16_t kSwTargetReached = 1u << 10;
constexpr std::uint16_t kSwSetPointAck = 1u << 12;     // homing mode: homing attained
constexpr std::uint16_t kSwFollowingError = 1u << 13;  // homing mode: homing error

enum class DriveState : std::uint8_t {
  NotReadyToSwitchOn,
  SwitchOnDisabled,
  ReadyToSwitchOn,
  SwitchedOn,
  OperationEnabled,
  QuickStopActive,
  FaultReactionActive,
  Fault,
};

inline DriveState decode_state(std::uint16_t sw) {
  if ((sw & 0x4F) == 0x00) return DriveState::NotReadyToSwitchOn;
  if ((sw & 0x4F) == 0x40) return DriveState::SwitchOnDisabled;
  if ((sw & 0x6F) == 0x21) return DriveState::ReadyToSwitchOn;
  if ((sw & 0x6F) == 0x23) return DriveState::SwitchedOn;
  if ((sw & 0x6F) == 0x27) return DriveState::OperationEnabled;
  if ((sw & 0x6F) == 0x07) return DriveState::QuickStopActive;
  if ((sw & 0x4F) == 0x0F) return DriveState::FaultReactionActive;
  if ((sw & 0x4F) == 0x08) return DriveState::Fault;
  return DriveState::NotReadyToSwitchOn;
}

inline const char* to_string(DriveState s) {
  switch (s) {
    case DriveState::NotReadyToSwitchOn:
      return "not-ready-to-switch-on";
    case DriveState::SwitchOnDisabled:
      return "switch-on-disabled";
    case DriveState::ReadyToSwitchOn:
      return "ready-to-switch-on";
    case DriveState::SwitchedOn:
      return "switched-on";
    case DriveState::OperationEnabled:
      return "operation-enabled";
    case DriveState::QuickStopActive:
      return "quick-stop-active";
    case DriveState::FaultReactionActive:
      return "fault-reaction-active";
    case DriveState::Fault:
      return "fault";
  }
  return "?";
}

// Little-endian helpers.
inline void put_u16(std::uint8_t* p, std::uint16_t v) {
  p[0] = v & 0xFF;
  p[1] = v >> 8;
}
inline void put_u32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
inline std::uint16_t get_u16(const std::uint8_t* p) { return static_cast<std::uint16_t>(p[0] | (p[1] << 8)); }
inline std::uint32_t get_u32(const std::uint8_t* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 |
         std::uint32_t(p[3]) << 24;
}

inline can_frame make_frame(std::uint32_t id, std::uint8_t len) {
  can_frame f;
  std::memset(&f, 0, sizeof f);
  f.can_id = id;
  f.len = len;
  return f;
}

// Expedited SDO download (write) of `size` (1, 2 or 4) bytes.
inline can_frame sdo_write(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t value,
                           std::uint8_t size) {
  can_frame f = make_frame(kSdoRx + node, 8);
  f.data[0] = static_cast<std::uint8_t>(kSdoWriteReq | ((4 - size) << 2) | 0x03);
  put_u16(f.data + 1, index);
  f.data[3] = sub;
  put_u32(f.data + 4, value);
  return f;
}
inline can_frame sdo_read(std::uint8_t node, std::uint16_t index, std::uint8_t sub) {
  can_frame f = make_frame(kSdoRx + node, 8);
  f.data[0] = kSdoReadReq;
  put_u16(f.data + 1, index);
  f.data[3] = sub;
  return f;
}
inline can_frame sdo_abort(std::uint32_t cob, std::uint16_t index, std::uint8_t sub, std::uint32_t code) {
  can_frame f = make_frame(cob, 8);
  f.data[0] = kSdoAbort;
  put_u16(f.data + 1, index);
  f.data[3] = sub;
  put_u32(f.data + 4, code);
  return f;
}
inline can_frame nmt(std::uint8_t command, std::uint8_t node) {
  can_frame f = make_frame(kNmt, 2);
  f.data[0] = command;
  f.data[1] = node;
  return f;
}

}  // namespace fs::cia402
