// The backends' hot paths allocate nothing after warm-up: CiA 402 master + twin polling with moves, V4L2 grab
// and release.
#include <gtest/gtest.h>

#include "can_rig.hpp"
#include "common/alloc_counter/alloc_counter.hpp"
#include "fake_v4l2.hpp"
#include "firmware/backends/v4l2_camera.hpp"

namespace fs::test {
namespace {

TEST(HotPathAllocations, Cia402MasterAndTwinPollWithoutAllocating) {
  CanRig rig;
  ASSERT_TRUE(rig.enable());
  ASSERT_TRUE(rig.move(100));  // warm-up
  fs::AllocCounter c;
  for (int k = 0; k < 20; ++k) {
    rig.master.move_to(k * 50, rig.clock.now());
    for (int i = 0; i < 50; ++i) rig.tick();
  }
  EXPECT_EQ(c.allocations(), 0u);
  EXPECT_TRUE(rig.status.enabled);
  EXPECT_EQ(rig.master.diagnostics().setpoints_acknowledged, 21u);
}

TEST(HotPathAllocations, V4l2GrabAndReleaseWithoutAllocating) {
  ManualClock clock;
  FakeV4l2 fake(clock);
  fw::V4l2Spec s;
  s.device = "/dev/fake0";
  s.width = 64;
  s.height = 16;
  fw::V4l2Camera cam(s, fake, &clock);
  cam.start(clock.now());
  std::uint64_t allocs = 0;
  for (std::uint32_t k = 0; k < 100; ++k) {
    ASSERT_TRUE(fake.produce(k, 1000 + k, [](std::uint8_t*, std::uint32_t) {}));
    fs::AllocCounter c;
    fw::FrameView f;
    ASSERT_EQ(cam.grab(clock.now() + kMs, f), fw::GrabResult::Ok);
    cam.release(f);
    if (k >= 4) allocs += c.allocations();  // after every buffer went round once
  }
  EXPECT_EQ(allocs, 0u);
}

}  // namespace
}  // namespace fs::test
