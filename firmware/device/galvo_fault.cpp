#include "firmware/device/galvo.hpp"

namespace fs::fw {

const char* to_string(GalvoFault f) {
  switch (f) {
    case GalvoFault::None:
      return "none";
    case GalvoFault::Stall:
      return "stall";
    case GalvoFault::MissedSteps:
      return "missed-steps";
    case GalvoFault::HomeNotFound:
      return "home-not-found";
    case GalvoFault::DriveFault:
      return "drive-fault";
    case GalvoFault::CommLost:
      return "comm-lost";
    case GalvoFault::BusOff:
      return "bus-off";
  }
  return "unknown";
}

}  // namespace fs::fw
