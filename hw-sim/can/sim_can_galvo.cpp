#include "hw-sim/can/sim_can_galvo.hpp"

#include <unistd.h>

#include <string>

#include "common/error.hpp"
#include "firmware/backends/factory.hpp"

namespace fs::sim {

SimCanGalvo::SimCanGalvo(fw::Clock& clock, const fw::Cia402Config& cfg, const Cia402TwinConfig& twin_cfg)
    : fds_(fw::CanPort::socketpair_fds()),
      port_(fds_[0], true),
      master_(port_, cfg),
      twin_(std::make_unique<Cia402Twin>(fds_[1], clock, twin_cfg)) {}

SimCanGalvo::~SimCanGalvo() {
  disable();
  ::close(fds_[1]);
}

void SimCanGalvo::enable(fw::Nanos now) { master_.enable(now); }
void SimCanGalvo::start_homing(fw::Nanos now) { master_.start_homing(now); }
void SimCanGalvo::move_to(std::int32_t step, fw::Nanos now) { master_.move_to(step, now); }
fw::GalvoStatus SimCanGalvo::poll(fw::Nanos now) {
  twin_->poll();
  return master_.poll(now);
}
void SimCanGalvo::reset_fault(fw::Nanos now) { master_.reset_fault(now); }
void SimCanGalvo::disable() noexcept {
  master_.disable();
  try {
    twin_->poll();  // let the twin see the disable (its position callback may throw)
  } catch (...) {
  }
}

SimCanBackend make_sim_can_galvo(std::string_view spec, fw::Clock& clock) {
  const fw::CanSpec c = fw::parse_can_spec(spec);
  if (!c.iface.empty()) throw Error("device spec '" + std::string(spec) + "': not a sim-can spec");
  Cia402TwinConfig t;
  t.node = c.node;
  auto g = std::make_unique<SimCanGalvo>(clock, fw::cia402_config(c), t);
  SimCanBackend b;
  b.twin = &g->twin();
  b.galvo = std::move(g);
  return b;
}

}  // namespace fs::sim
