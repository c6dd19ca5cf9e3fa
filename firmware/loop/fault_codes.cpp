#include "firmware/loop/fault_codes.hpp"

namespace fs::fw {

const char* to_string(FaultCode c) {
  switch (c) {
    case FaultCode::None:
      return "none";
    case FaultCode::GalvoStall:
      return "galvo stall";
    case FaultCode::GalvoMissedSteps:
      return "galvo missed steps";
    case FaultCode::HomeNotFound:
      return "home switch not found";
    case FaultCode::GalvoDrive:
      return "galvo drive fault";
    case FaultCode::GalvoCommLost:
      return "galvo communication lost";
    case FaultCode::GalvoBusOff:
      return "galvo CAN bus-off";
    case FaultCode::MoveTimeout:
      return "galvo move timeout";
    case FaultCode::CameraTimeout:
      return "camera timeout";
    case FaultCode::CameraError:
      return "camera error";
    case FaultCode::FrameSaturated:
      return "saturated frames";
    case FaultCode::LaserMonitorMismatch:
      return "laser monitor disagrees with the command (line stuck)";
    case FaultCode::DwellOverrun:
      return "laser dwell limit exceeded";
    case FaultCode::DeadlineMissed:
      return "loop deadlines missed";
    case FaultCode::HostLost:
      return "host connection lost";
    case FaultCode::Stopped:
      return "stopped";
    case FaultCode::FramesDropped:
      return "camera frames dropped";
    case FaultCode::SaturatedRetry:
      return "saturated frame, step repeated";
    case FaultCode::StripesDropped:
      return "stripes dropped";
  }
  return "unknown";
}

FaultCode fault_code_for(GalvoFault f) {
  switch (f) {
    case GalvoFault::None:
      return FaultCode::None;
    case GalvoFault::Stall:
      return FaultCode::GalvoStall;
    case GalvoFault::MissedSteps:
      return FaultCode::GalvoMissedSteps;
    case GalvoFault::HomeNotFound:
      return FaultCode::HomeNotFound;
    case GalvoFault::DriveFault:
      return FaultCode::GalvoDrive;
    case GalvoFault::CommLost:
      return FaultCode::GalvoCommLost;
    case GalvoFault::BusOff:
      return FaultCode::GalvoBusOff;
  }
  return FaultCode::GalvoDrive;
}

}  // namespace fs::fw
