// The same controller loop with the CiA 402 galvo (backends' master) driving the hw-sim drive twin over a
// socketpair; the twin's position feeds the mirror model the camera twin renders from.
#include <gtest/gtest.h>

#ifdef FACETSCAN_HAVE_BACKENDS
#include <cmath>

#include "hil_support.hpp"
#include "hw-sim/can/cia402_twin.hpp"
#include "hw-sim/can/sim_can_galvo.hpp"

namespace fs::test {
namespace {

TEST(SimCanHil, ScansWithTheCia402Drive) {
  constexpr std::uint32_t kSteps = 20;
  const ScannerCalibration cal = small_calibration(kSteps);
  sim::TableStripeRenderer renderer(cal);
  sim::SimRig rig(renderer);
  auto b = sim::make_sim_can_galvo("sim-can", rig.clock);
  sim::SimMirror* mirror = &rig.mirror;
  b.twin->set_position_callback([mirror](double pos, std::int64_t t) { mirror->command(t, pos); });
  wire::VectorSink sink;
  fw::QueuedPublisherConfig pc;
  pc.block_when_full = true;
  pc.max_points = cal.camera.height;
  fw::QueuedPublisher pub(sink, pc);
  fw::LoopConfig cfg;
  cfg.steps = kSteps;
  cfg.max_rows = cal.camera.height;
  fw::Controller ctl(fw::Devices{rig.clock, *b.galvo, rig.laser, rig.camera}, cfg, pub, cal);
  const auto& r = ctl.run();
  ASSERT_EQ(r.state, fw::State::Done) << fw::to_string(r.fault);
  pub.flush();
  const Decoded d = decode_all(sink.data);
  ASSERT_EQ(d.stripes.size(), kSteps);
  std::vector<double> truth(cal.camera.height);
  for (std::size_t i = 0; i < d.stripes.size(); ++i) {
    const sim::FrameRecord* rec = rig.camera.find(d.stripes[i].frame_sequence);
    ASSERT_NE(rec, nullptr);
    EXPECT_NEAR(rec->mirror_step, static_cast<double>(i), 0.05);
    renderer.truth(static_cast<double>(i), truth);
    for (const auto& p : d.points[i]) EXPECT_NEAR(p.col, truth[p.row], 0.3);
  }
  // The laser was never on while the drive moved the mirror.
  for (const auto& ev : rig.laser.log()) {
    if (ev.commanded) {
      EXPECT_NEAR(rig.mirror.position_at(ev.t), std::round(rig.mirror.position_at(ev.t)), 0.05);
    }
  }
}

}  // namespace
}  // namespace fs::test
#endif
