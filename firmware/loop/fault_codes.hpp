#pragma once
// Codes of msg::Fault and ScanEnd::last_fault_code. 1-99: fatal (the loop goes to Fault, laser off, galvo
// disabled); 100+: warnings (the scan continues; reported in a Fault message and counted in ScanEnd).
#include <cstdint>

#include "firmware/device/galvo.hpp"

namespace fs::fw {

enum class FaultCode : std::uint32_t {
  None = 0,
  GalvoStall = 1,
  GalvoMissedSteps = 2,
  HomeNotFound = 3,
  GalvoDrive = 4,
  GalvoCommLost = 5,
  GalvoBusOff = 6,
  MoveTimeout = 7,
  CameraTimeout = 10,
  CameraError = 11,
  FrameSaturated = 12,  // still saturated after the retries
  LaserMonitorMismatch = 20,
  DwellOverrun = 21,
  DeadlineMissed = 22,
  HostLost = 23,
  Stopped = 24,  // stop requested (signal)
  // warnings
  FramesDropped = 100,
  SaturatedRetry = 101,
  StripesDropped = 102,
};

const char* to_string(FaultCode c);
FaultCode fault_code_for(GalvoFault f);
inline bool is_fatal(FaultCode c) { return c != FaultCode::None && static_cast<std::uint32_t>(c) < 100; }

}  // namespace fs::fw
