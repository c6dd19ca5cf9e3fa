#include "firmware/galvo/can_galvo.hpp"

#include <utility>

namespace fs::fw {

CanGalvo::CanGalvo(CanPort port, const Cia402Config& cfg) : port_(std::move(port)), master_(port_, cfg) {}

CanGalvo::~CanGalvo() { master_.disable(); }

std::unique_ptr<CanGalvo> CanGalvo::open(const std::string& iface, const Cia402Config& cfg) {
  constexpr canid_t mask = CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG;
  const can_filter filters[] = {
      {cia402::kEmcy + cfg.node, mask},
      {cia402::kTpdo1 + cfg.node, mask},
      {cia402::kSdoTx + cfg.node, mask},
      {cia402::kHeartbeat + cfg.node, mask},
  };
  return std::make_unique<CanGalvo>(CanPort::open_raw(iface, filters), cfg);
}

}  // namespace fs::fw
