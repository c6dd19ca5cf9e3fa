// The real-time setup's CPU wake-up latency limit (PM QoS): held while the limit object lives, released
// when it goes; a refused request is a warning, not an error.
#include <fcntl.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <thread>

#include "firmware/loop/realtime.hpp"

namespace {

constexpr const char* kDevice = "/dev/cpu_dma_latency";

// The limit in force (the smallest held request; the device reads it as a binary 32-bit value).
std::int32_t current_limit() {
  const int fd = ::open(kDevice, O_RDONLY | O_CLOEXEC);
  std::int32_t v = -1;
  if (fd >= 0) {
    if (::read(fd, &v, sizeof v) != static_cast<ssize_t>(sizeof v)) v = -1;
    ::close(fd);
  }
  return v;
}

TEST(CpuLatencyLimit, HeldWhileItLivesAndReleasedAfter) {
  if (::access(kDevice, R_OK | W_OK) != 0) GTEST_SKIP() << kDevice << " not accessible here";
  const std::int32_t before = current_limit();
  ASSERT_GT(before, 7);
  {
    fs::fw::CpuLatencyLimit limit;
    std::string err;
    ASSERT_TRUE(limit.request(7, &err)) << err;
    EXPECT_TRUE(limit.held());
    EXPECT_EQ(current_limit(), 7);
    // Moved: still one request, held by the new owner.
    fs::fw::CpuLatencyLimit moved = std::move(limit);
    EXPECT_TRUE(moved.held());
    EXPECT_FALSE(limit.held());  // NOLINT(bugprone-use-after-move): the moved-from state is specified
    EXPECT_EQ(current_limit(), 7);
  }
  EXPECT_EQ(current_limit(), before);
}

TEST(CpuLatencyLimit, RefusedDeviceIsReportedWithItsName) {
  const auto missing = std::filesystem::temp_directory_path() / "facetscan-no-such-dir" / "cpu_dma_latency";
  fs::fw::CpuLatencyLimit limit;
  std::string err;
  EXPECT_FALSE(limit.request(0, &err, missing.c_str()));
  EXPECT_FALSE(limit.held());
  EXPECT_NE(err.find(missing.string()), std::string::npos) << err;
}

TEST(ApplyRealtime, LatencyLimitIsPartOfTheResult) {
  if (::access(kDevice, R_OK | W_OK) != 0) GTEST_SKIP() << kDevice << " not accessible here";
  const std::int32_t before = current_limit();
  // On a thread of its own: apply_realtime() changes the calling thread's scheduling.
  std::thread([&] {
    fs::fw::RealtimeRequest rq;
    rq.lock_memory = false;  // the test process stays as it is
    rq.priority = 1;
    rq.cpu_latency_us = 3;
    {
      const fs::fw::RealtimeResult r = fs::fw::apply_realtime(rq);
      EXPECT_TRUE(r.cpu_latency.held());
      EXPECT_EQ(current_limit(), 3);
    }
    EXPECT_EQ(current_limit(), before);
    rq.cpu_latency_us = -1;  // leave the idle states alone
    const fs::fw::RealtimeResult r = fs::fw::apply_realtime(rq);
    EXPECT_FALSE(r.cpu_latency.held());
    EXPECT_EQ(current_limit(), before);
  }).join();
}

}  // namespace
