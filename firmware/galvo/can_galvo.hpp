#pragma once
// Galvo on a CiA 402 drive: a CanPort (raw SocketCAN socket or socketpair end) + Cia402Master.
#include <memory>
#include <string>

#include "firmware/backends/can_port.hpp"
#include "firmware/backends/cia402_master.hpp"
#include "firmware/device/galvo.hpp"

namespace fs::fw {

class CanGalvo : public Galvo {
 public:
  CanGalvo(CanPort port, const Cia402Config& cfg);
  // Raw socket on `iface` filtered to the drive's COB-IDs (EMCY, TPDO1, SDO response, heartbeat).
  static std::unique_ptr<CanGalvo> open(const std::string& iface, const Cia402Config& cfg);
  ~CanGalvo() override;

  void enable(Nanos now) override { master_.enable(now); }
  void start_homing(Nanos now) override { master_.start_homing(now); }
  void move_to(std::int32_t step, Nanos now) override { master_.move_to(step, now); }
  GalvoStatus poll(Nanos now) override { return master_.poll(now); }
  void reset_fault(Nanos now) override { master_.reset_fault(now); }
  void disable() noexcept override { master_.disable(); }

  const Cia402Master& master() const { return master_; }
  const CanPort& port() const { return port_; }

 private:
  CanPort port_;
  Cia402Master master_;
};

}  // namespace fs::fw
