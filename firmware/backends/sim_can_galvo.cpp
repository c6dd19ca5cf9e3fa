#include "firmware/backends/sim_can_galvo.hpp"

#include <unistd.h>

namespace fs::fw {

SimCanGalvo::SimCanGalvo(Clock& clock, const Cia402Config& cfg, const sim::Cia402TwinConfig& twin_cfg)
    : fds_(CanPort::socketpair_fds()),
      port_(fds_[0], true),
      master_(port_, cfg),
      twin_(std::make_unique<sim::Cia402Twin>(fds_[1], clock, twin_cfg)) {}

SimCanGalvo::~SimCanGalvo() {
  disable();
  ::close(fds_[1]);
}

void SimCanGalvo::enable(Nanos now) { master_.enable(now); }
void SimCanGalvo::start_homing(Nanos now) { master_.start_homing(now); }
void SimCanGalvo::move_to(std::int32_t step, Nanos now) { master_.move_to(step, now); }
GalvoStatus SimCanGalvo::poll(Nanos now) {
  twin_->poll();
  return master_.poll(now);
}
void SimCanGalvo::reset_fault(Nanos now) { master_.reset_fault(now); }
void SimCanGalvo::disable() noexcept {
  master_.disable();
  try {
    twin_->poll();  // let the twin see the disable (its position callback may throw)
  } catch (...) {
  }
}

}  // namespace fs::fw
