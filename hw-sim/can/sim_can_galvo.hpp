#pragma once
// `--galvo sim-can` (facetscan-fw-hil): the firmware's real CiA 402 master (firmware/backends/) driving the
// drive twin (hw-sim/can/cia402_twin.hpp) over a socketpair. poll() and the commands service the twin first,
// so with a SimClock the whole exchange is deterministic (no threads). Allocates only at construction.
#include <array>
#include <memory>
#include <string_view>

#include "firmware/backends/can_port.hpp"
#include "firmware/backends/cia402_master.hpp"
#include "firmware/device/clock.hpp"
#include "firmware/device/galvo.hpp"
#include "hw-sim/can/cia402_twin.hpp"

namespace fs::sim {

class SimCanGalvo : public fw::Galvo {
 public:
  SimCanGalvo(fw::Clock& clock, const fw::Cia402Config& cfg, const Cia402TwinConfig& twin_cfg);
  ~SimCanGalvo() override;

  void enable(fw::Nanos now) override;
  void start_homing(fw::Nanos now) override;
  void move_to(std::int32_t step, fw::Nanos now) override;
  fw::GalvoStatus poll(fw::Nanos now) override;
  void reset_fault(fw::Nanos now) override;
  void disable() noexcept override;

  Cia402Twin& twin() { return *twin_; }
  const fw::Cia402Master& master() const { return master_; }

 private:
  std::array<int, 2> fds_;
  fw::CanPort port_;
  fw::Cia402Master master_;
  std::unique_ptr<Cia402Twin> twin_;
};

// The master + twin pair from a `sim-can[:node=N][,hb=MS,...]` spec (the keys of the can: spec, parsed by
// fw::parse_can_spec). `twin` stays valid as long as `galvo` lives (set its position callback to feed the
// mirror the camera twin renders from). Throws fs::Error for a malformed or non-sim-can spec.
struct SimCanBackend {
  std::unique_ptr<fw::Galvo> galvo;
  Cia402Twin* twin = nullptr;
};
SimCanBackend make_sim_can_galvo(std::string_view spec, fw::Clock& clock);

}  // namespace fs::sim
