#pragma once
// `--galvo sim-can`: the real CiA 402 master driving the hw-sim drive twin over a socketpair. poll() and the
// commands service the twin first, so with a SimClock the whole exchange is deterministic (no threads).
#include <memory>

#include "firmware/backends/can_port.hpp"
#include "firmware/backends/cia402_master.hpp"
#include "firmware/device/galvo.hpp"
#include "hw-sim/can/cia402_twin.hpp"

namespace fs::fw {

class SimCanGalvo : public Galvo {
 public:
  SimCanGalvo(Clock& clock, const Cia402Config& cfg, const sim::Cia402TwinConfig& twin_cfg);
  ~SimCanGalvo() override;

  void enable(Nanos now) override;
  void start_homing(Nanos now) override;
  void move_to(std::int32_t step, Nanos now) override;
  GalvoStatus poll(Nanos now) override;
  void reset_fault(Nanos now) override;
  void disable() noexcept override;

  sim::Cia402Twin& twin() { return *twin_; }
  const Cia402Master& master() const { return master_; }

 private:
  std::array<int, 2> fds_;
  CanPort port_;
  Cia402Master master_;
  std::unique_ptr<sim::Cia402Twin> twin_;
};

}  // namespace fs::fw
