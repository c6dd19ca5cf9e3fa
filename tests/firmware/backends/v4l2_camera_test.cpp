// V4l2Camera against the fd-level fake driver: negotiation, streaming, zero copy, drops, EINTR/EAGAIN,
// timeouts.
#include <gtest/gtest.h>

#include "common/error.hpp"
#include "fake_v4l2.hpp"
#include "firmware/backends/v4l2_camera.hpp"
#include "support/error_of.hpp"

namespace fs::test {
namespace {

fw::V4l2Spec spec(fw::V4l2Fourcc f = fw::V4l2Fourcc::Grey, std::uint32_t w = 64, std::uint32_t h = 32) {
  fw::V4l2Spec s;
  s.device = "/dev/fake0";
  s.format = f;
  s.width = w;
  s.height = h;
  return s;
}

using fs::test::error_of;

void stripe(std::uint8_t* d, std::uint32_t stride, std::uint32_t h, std::uint32_t col) {
  for (std::uint32_t y = 0; y < h; ++y) {
    std::memset(d + y * stride, 10, stride);
    d[y * stride + col] = 200;
  }
}

TEST(V4l2Camera, NegotiatesEachFormatAndMapsFourBuffers) {
  ManualClock clock;
  const std::pair<fw::V4l2Fourcc, fw::PixelFormat> cases[] = {{fw::V4l2Fourcc::Grey, fw::PixelFormat::Mono8},
                                                              {fw::V4l2Fourcc::Y16, fw::PixelFormat::Mono16},
                                                              {fw::V4l2Fourcc::Yuyv, fw::PixelFormat::Yuyv}};
  for (auto [fourcc, pf] : cases) {
    FakeV4l2 fake(clock);
    fake.stride_pad = 16;
    {
      fw::V4l2Camera cam(spec(fourcc), fake);
      EXPECT_EQ(cam.format(), pf);
      EXPECT_EQ(cam.width(), 64u);
      EXPECT_EQ(cam.height(), 32u);
      EXPECT_EQ(cam.stride(), (pf == fw::PixelFormat::Mono8 ? 64u : 128u) + 16u);
      EXPECT_EQ(cam.buffer_count(), 4u);
      EXPECT_EQ(cam.driver(), "fakecam");
      EXPECT_EQ(fake.mapped, 4);
    }
    EXPECT_EQ(fake.mapped, 0);  // unmapped and closed on destruction
    EXPECT_EQ(fake.open_fds, 0);
  }
}

TEST(V4l2Camera, RefusesWhatItCannotUse) {
  ManualClock clock;
  {
    FakeV4l2 fake(clock);
    fake.formats = {V4L2_PIX_FMT_YUYV};
    const auto e = error_of([&] { fw::V4l2Camera cam(spec(fw::V4l2Fourcc::Y16), fake); });
    EXPECT_NE(e.find("format Y16  not supported (driver chose YUYV)"), std::string::npos) << e;
    EXPECT_EQ(fake.open_fds, 0);
  }
  {
    FakeV4l2 fake(clock);
    fake.device_caps = V4L2_CAP_VIDEO_OUTPUT | V4L2_CAP_STREAMING;
    EXPECT_NE(error_of([&] { fw::V4l2Camera cam(spec(), fake); }).find("not a single-planar video capture"),
              std::string::npos);
  }
  {
    FakeV4l2 fake(clock);
    fake.device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_READWRITE;
    EXPECT_NE(error_of([&] { fw::V4l2Camera cam(spec(), fake); }).find("no streaming I/O"),
              std::string::npos);
  }
  {
    FakeV4l2 fake(clock);
    fake.grant_buffers = 2;
    const auto e = error_of([&] { fw::V4l2Camera cam(spec(), fake); });
    EXPECT_NE(e.find("granted 2 MMAP buffers, need 4"), std::string::npos) << e;
    EXPECT_EQ(fake.mapped, 0);
    EXPECT_EQ(fake.open_fds, 0);
  }
  {
    FakeV4l2 fake(clock);
    auto s = spec();
    s.exposure = 99999;
    EXPECT_NE(error_of([&] { fw::V4l2Camera cam(s, fake); }).find("outside the driver's range 1..5000"),
              std::string::npos);
  }
  {
    FakeV4l2 fake(clock);
    auto s = spec();
    s.device = "/dev/nothing";
    EXPECT_NE(error_of([&] { fw::V4l2Camera cam(s, fake); }).find("'/dev/nothing': cannot open"),
              std::string::npos);
  }
}

TEST(V4l2Camera, SetsFrameRateAndExposureWhereSupported) {
  ManualClock clock;
  FakeV4l2 fake(clock);
  auto s = spec();
  s.fps = 120;
  s.exposure = 40;
  fw::V4l2Camera cam(s, fake);
  EXPECT_EQ(fake.fps_num, 1u);
  EXPECT_EQ(fake.fps_den, 120u);
  EXPECT_TRUE(fake.manual_exposure);
  EXPECT_EQ(fake.exposure, 40);
  EXPECT_EQ(cam.notes(), "");

  FakeV4l2 bare(clock);
  bare.timeperframe = false;
  bare.exposure_ctrl = false;
  fw::V4l2Camera cam2(s, bare);
  EXPECT_NE(cam2.notes().find("frame rate not settable"), std::string::npos);
  EXPECT_NE(cam2.notes().find("no exposure control"), std::string::npos);
}

TEST(V4l2Camera, StreamsZeroCopyAndRecyclesBuffers) {
  ManualClock clock;
  FakeV4l2 fake(clock);
  fw::V4l2Camera cam(spec(), fake);
  cam.start(clock.now());
  EXPECT_EQ(fake.queued(), 4u);
  for (std::uint32_t k = 0; k < 20; ++k) {
    const fw::Nanos ts = 5'000'000'000 + k * 10 * kMs;
    ASSERT_TRUE(fake.produce(k, ts, [&](std::uint8_t* d, std::uint32_t st) { stripe(d, st, 32, 3 + k); }));
    fw::FrameView f;
    ASSERT_EQ(cam.grab(clock.now() + 100 * kMs, f), fw::GrabResult::Ok);
    EXPECT_EQ(f.sequence, k);
    EXPECT_EQ(f.timestamp, ts);
    EXPECT_EQ(f.width, 64u);
    EXPECT_EQ(f.stride, 64u);
    EXPECT_TRUE(cam.owns_pointer(f.data));
    EXPECT_EQ(f.data, fake.buffer(f.buffer));  // the driver's buffer itself, no copy
    EXPECT_EQ(f.data[5 * 64 + 3 + k], 200);
    EXPECT_EQ(fake.queued(), 3u);  // handed out until release
    cam.release(f);
    EXPECT_EQ(fake.queued(), 4u);
  }
  EXPECT_EQ(cam.frames_dropped(), 0u);
  EXPECT_EQ(cam.stats().frames, 20u);
  // double release is an error, not a corrupted queue
  fw::FrameView f;
  ASSERT_TRUE(fake.produce(20, 1, [](std::uint8_t*, std::uint32_t) {}));
  ASSERT_EQ(cam.grab(clock.now() + 100 * kMs, f), fw::GrabResult::Ok);
  cam.release(f);
  EXPECT_THROW(cam.release(f), fs::Error);
}

TEST(V4l2Camera, SequenceGapsAndErrorBuffersCountAsDrops) {
  ManualClock clock;
  FakeV4l2 fake(clock);
  fw::V4l2Camera cam(spec(), fake);
  cam.start(clock.now());
  auto grab_seq = [&](std::uint32_t seq, std::uint32_t flags = 0, std::uint32_t bytes = 0) {
    EXPECT_TRUE(fake.produce(
        seq, 1000, [](std::uint8_t*, std::uint32_t) {}, flags, bytes));
  };
  fw::FrameView f;
  grab_seq(0);
  ASSERT_EQ(cam.grab(clock.now() + kMs, f), fw::GrabResult::Ok);
  cam.release(f);
  grab_seq(3);  // 1 and 2 lost
  ASSERT_EQ(cam.grab(clock.now() + kMs, f), fw::GrabResult::Ok);
  EXPECT_EQ(f.sequence, 3u);
  cam.release(f);
  EXPECT_EQ(cam.frames_dropped(), 2u);
  grab_seq(4, V4L2_BUF_FLAG_ERROR);  // corrupted: re-queued, counted
  grab_seq(5, 0, 100);               // short
  grab_seq(6);
  ASSERT_EQ(cam.grab(clock.now() + kMs, f), fw::GrabResult::Ok);
  EXPECT_EQ(f.sequence, 6u);
  cam.release(f);
  EXPECT_EQ(cam.frames_dropped(), 4u);
  EXPECT_EQ(cam.stats().error_buffers, 2u);
  EXPECT_EQ(fake.queued(), 4u);
  grab_seq(1);  // the driver restarted its count: not thousands of drops
  ASSERT_EQ(cam.grab(clock.now() + kMs, f), fw::GrabResult::Ok);
  cam.release(f);
  EXPECT_EQ(cam.frames_dropped(), 4u);
  EXPECT_EQ(cam.stats().sequence_restarts, 1u);
  grab_seq(0xFFFFFFFFu);  // far ahead, then wrap to 1: one frame (0) lost over the wrap
  ASSERT_EQ(cam.grab(clock.now() + kMs, f), fw::GrabResult::Ok);
  cam.release(f);
  const auto before = cam.frames_dropped();
  grab_seq(1);
  ASSERT_EQ(cam.grab(clock.now() + kMs, f), fw::GrabResult::Ok);
  cam.release(f);
  EXPECT_EQ(cam.frames_dropped(), before + 1);
}

TEST(V4l2Camera, TimeoutEintrEagainAndNonMonotonicTimestamps) {
  ManualClock clock;
  FakeV4l2 fake(clock);
  fake.timestamp_flags = V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN;
  fw::V4l2Camera cam(spec(), fake, &clock);
  cam.start(clock.now());
  fw::FrameView f;
  const fw::Nanos t0 = clock.now();
  EXPECT_EQ(cam.grab(t0 + 25 * kMs, f), fw::GrabResult::Timeout);
  EXPECT_GE(clock.now(), t0 + 25 * kMs);
  EXPECT_LT(clock.now(), t0 + 27 * kMs);
  EXPECT_GE(cam.stats().eagain, 1u);
  fake.eintr_dqbuf = 2;
  fake.eintr_poll = 1;
  ASSERT_TRUE(fake.produce(0, 777, [](std::uint8_t*, std::uint32_t) {}));
  ASSERT_EQ(cam.grab(clock.now() + 10 * kMs, f), fw::GrabResult::Ok);
  EXPECT_EQ(cam.stats().eintr, 2u);
  EXPECT_EQ(f.timestamp, clock.now());  // not CLOCK_MONOTONIC: the dequeue time on the loop's clock
  EXPECT_EQ(cam.stats().non_monotonic, 1u);
  cam.release(f);
  cam.stop();
  EXPECT_FALSE(fake.streaming);
  EXPECT_EQ(cam.grab(clock.now() + kMs, f), fw::GrabResult::Error);
  cam.start(clock.now());  // restart re-queues every buffer
  EXPECT_EQ(fake.queued(), 4u);
}

}  // namespace
}  // namespace fs::test
