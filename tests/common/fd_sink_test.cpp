#include "common/fd_sink.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <unistd.h>

#include <fcntl.h>

#include <thread>

#include "common/scan_file.hpp"
#include "wire_samples.hpp"

namespace {

using ::testing::HasSubstr;

TEST(FdSink, StreamsFramesOverASocketToADecoder) {
  int sv[2];
  ASSERT_EQ(::socketpair(AF_UNIX, SOCK_STREAM, 0, sv), 0);
  auto pts = fs::test::sample_points(3000);  // frames larger than the socket buffer: partial writes
  std::thread producer([&] {
    fs::wire::FdSink sink(sv[0], "sock");
    fs::wire::FrameWriter w(sink);
    w.send(fs::test::sample_scan_begin());
    for (std::uint32_t k = 0; k < 40; ++k) w.send(fs::msg::Stripe{fs::test::sample_stripe_header(k), pts});
    w.send(fs::test::sample_scan_end());
    ::close(sv[0]);
  });
  fs::wire::FrameDecoder dec("sock");
  fs::wire::DecodedMessage m;
  std::vector<std::uint8_t> buf(5000);
  int stripes = 0, ends = 0;
  for (;;) {
    const ssize_t n = ::read(sv[1], buf.data(), buf.size());
    ASSERT_GE(n, 0);
    if (n == 0) break;
    std::span<const std::uint8_t> in(buf.data(), static_cast<std::size_t>(n));
    while (!in.empty()) {
      in = in.subspan(dec.feed(in));
      for (fs::wire::FrameView f; dec.next(f);) {
        fs::wire::decode(f, m);
        if (m.type == fs::msg::Type::Stripe) {
          EXPECT_EQ(m.stripe.header.step_index, static_cast<std::uint32_t>(stripes));
          EXPECT_EQ(m.stripe.points.size(), 3000u);
          ++stripes;
        }
        ends += m.type == fs::msg::Type::ScanEnd;
      }
    }
  }
  dec.finish();
  producer.join();
  ::close(sv[1]);
  EXPECT_EQ(stripes, 40);
  EXPECT_EQ(ends, 1);
  EXPECT_EQ(dec.sequence_gaps(), 0u);
}

TEST(FdSink, PeerGoneIsAnErrorNotSigpipe) {
  int sv[2];
  ASSERT_EQ(::socketpair(AF_UNIX, SOCK_STREAM, 0, sv), 0);
  ::close(sv[1]);
  fs::wire::FdSink sink(sv[0], "tcp host");
  fs::wire::FrameWriter w(sink);
  try {
    w.send(fs::test::sample_heartbeat());
    FAIL() << "no error";
  } catch (const fs::Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("tcp host: at byte 0: write failed"));
  }
  ::close(sv[0]);
}

TEST(ScanFileWriterIo, FullDiskIsReported) {
  if (::access("/dev/full", W_OK) != 0) GTEST_SKIP() << "no /dev/full";
  fs::ScanFileWriter w("/dev/full");
  fs::wire::FrameWriter fw(w);
  std::string err;
  try {
    auto pts = fs::test::sample_points(8000);
    for (int i = 0; i < 10; ++i) fw.send(fs::msg::Stripe{fs::test::sample_stripe_header(0), pts});
    w.close();
  } catch (const fs::Error& e) {
    err = e.what();
  }
  EXPECT_THAT(err, HasSubstr("/dev/full: at byte"));
  EXPECT_THAT(err, HasSubstr("No space left on device"));
}

}  // namespace
