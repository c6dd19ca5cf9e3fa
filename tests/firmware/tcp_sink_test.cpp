// TCP streaming: connect, reconnect with backoff after the host drops the connection (buffered frames are
// delivered, a cut frame is resent whole), bounded buffer with counted drops, host heartbeat timeout.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <thread>
#include <vector>

#include "common/error.hpp"
#include "common/wire.hpp"
#include "firmware/stream/tcp_sink.hpp"
#include "hw-sim/sim_clock.hpp"

namespace fs::fw {
namespace {

struct Listener {
  Listener() {
    fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    int one = 1;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    socklen_t len = sizeof a;
    getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
    port = ntohs(a.sin_port);
    listen(fd, 4);
  }
  ~Listener() { close(fd); }
  int accept_within(int ms) {
    pollfd p{fd, POLLIN, 0};
    if (poll(&p, 1, ms) != 1) return -1;
    return accept(fd, nullptr, nullptr);
  }
  std::string address() const { return "127.0.0.1:" + std::to_string(port); }
  int fd = -1;
  std::uint16_t port = 0;
};

std::vector<std::uint8_t> heartbeat_frame(std::uint64_t counter) {
  msg::Heartbeat hb;
  hb.counter = counter;
  std::vector<std::uint8_t> b(wire::frame_size(hb));
  wire::encode(b, static_cast<std::uint32_t>(counter), hb);
  return b;
}

std::vector<std::uint8_t> stripe_frame(std::uint32_t step) {
  msg::Stripe s;
  s.header.step_index = step;
  std::vector<std::uint8_t> b(wire::frame_size(s));
  wire::encode(b, step, s);
  return b;
}

// Reads frames from fd until `n` heartbeats arrived or the timeout; returns their counters.
std::vector<std::uint64_t> read_heartbeats(int fd, std::size_t n, int timeout_ms) {
  wire::FrameDecoder dec("test");
  wire::DecodedMessage m;
  std::vector<std::uint64_t> got;
  std::vector<std::uint8_t> buf(4096);
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  while (got.size() < n && std::chrono::steady_clock::now() < end) {
    pollfd p{fd, POLLIN, 0};
    if (poll(&p, 1, 20) != 1) continue;
    const ssize_t r = recv(fd, buf.data(), buf.size(), 0);
    if (r <= 0) break;
    std::span<const std::uint8_t> in(buf.data(), static_cast<std::size_t>(r));
    while (!in.empty()) {
      in = in.subspan(dec.feed(in));
      wire::FrameView f;
      while (dec.next(f)) {
        wire::decode(f, m);
        if (m.type == msg::Type::Heartbeat) got.push_back(m.heartbeat.counter);
      }
    }
  }
  return got;
}

TcpSinkConfig fast() {
  TcpSinkConfig c;
  c.backoff_min = 5'000'000;
  c.backoff_max = 40'000'000;
  return c;
}

TEST(TcpSink, DeliversAndReconnectsWithBufferedFrames) {
  Listener l;
  TcpSink sink(l.address(), fast());
  const int c1 = l.accept_within(3000);
  ASSERT_GE(c1, 0);
  for (int i = 0; i < 3; ++i) sink.write(heartbeat_frame(i));
  EXPECT_EQ(read_heartbeats(c1, 3, 3000), (std::vector<std::uint64_t>{0, 1, 2}));
  close(c1);  // the host goes away; the sink notices (EOF) and connects again (the listener's backlog
              // completes the connection at once, so frames written now may be sent before accept())
  for (int i = 0; i < 300 && sink.connections() < 2; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ(sink.connections(), 2u);
  for (int i = 3; i < 8; ++i) sink.write(heartbeat_frame(i));
  const int c2 = l.accept_within(3000);
  ASSERT_GE(c2, 0);
  EXPECT_EQ(read_heartbeats(c2, 5, 3000), (std::vector<std::uint64_t>{3, 4, 5, 6, 7}));
  EXPECT_TRUE(sink.drain(2'000'000'000));
  EXPECT_GE(sink.connections(), 2u);
  EXPECT_EQ(sink.frames_dropped(), 0u);
  close(c2);
}

TEST(TcpSink, BoundedBufferCountsDroppedStripes) {
  const auto one = stripe_frame(0);
  TcpSinkConfig cfg = fast();
  cfg.buffer_bytes = 3 * one.size();
  TcpSink sink("127.0.0.1:1", cfg);  // nothing listens there: stays disconnected
  for (std::uint32_t i = 0; i < 10; ++i) sink.write(stripe_frame(i));
  EXPECT_FALSE(sink.connected());
  EXPECT_EQ(sink.frames_dropped(), 7u);
  EXPECT_EQ(sink.buffered_bytes(), 3 * one.size());
}

// Waits (bounded) until pred() holds; the assertions are on the state, not on the time taken.
template <class P>
bool eventually(P pred) {
  for (int i = 0; i < 1000 && !pred(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  return pred();
}

// The heartbeats' time is the sink's clock (TcpSinkConfig::heartbeat_clock), moved by the test: a thread
// that runs late on a loaded machine does not look like a silent host.
TEST(TcpSink, HostHeartbeatTimeout) {
  Listener l;
  fs::sim::SimClock clock;  // virtual: it moves only when the test says so
  TcpSinkConfig cfg = fast();
  cfg.host_heartbeat_timeout = 60'000'000;
  cfg.heartbeat_clock = &clock;
  {
    TcpSink sink(l.address(), cfg);
    const int c = l.accept_within(3000);
    ASSERT_GE(c, 0);
    // The host sends a heartbeat every 10 ms of that clock: the link stays up.
    for (int i = 0; i < 20; ++i) {
      const auto hb = heartbeat_frame(static_cast<std::uint64_t>(i));
      ASSERT_EQ(send(c, hb.data(), hb.size(), MSG_NOSIGNAL), static_cast<ssize_t>(hb.size()));
      ASSERT_TRUE(eventually([&] { return sink.host_heartbeats() >= static_cast<std::uint64_t>(i + 1); }));
      clock.advance(10'000'000);
    }
    EXPECT_TRUE(sink.connected());
    EXPECT_EQ(sink.connections(), 1u);
    EXPECT_EQ(sink.host_heartbeats(), 20u);
    // Silence past the timeout: the sink gives up on this connection and reconnects.
    clock.advance(61'000'000);
    const int c2 = l.accept_within(3000);
    EXPECT_GE(c2, 0);
    EXPECT_TRUE(eventually([&] { return sink.connections() >= 2u; }));
    close(c);
    if (c2 >= 0) close(c2);
  }
}

TEST(TcpSink, CountsStripesTheHostAcknowledged) {
  Listener l;
  TcpSink sink(l.address(), fast());
  const int c = l.accept_within(3000);
  ASSERT_GE(c, 0);
  for (std::uint32_t i = 0; i < 20; ++i) sink.write(stripe_frame(i));
  sink.write(heartbeat_frame(0));  // not a stripe: not counted
  // The host reads everything.
  std::vector<std::uint8_t> buf(1 << 16);
  std::size_t got = 0;
  const std::size_t want = 20 * stripe_frame(0).size() + heartbeat_frame(0).size();
  while (got < want) {
    const ssize_t n = recv(c, buf.data(), buf.size(), 0);
    ASSERT_GT(n, 0);
    got += static_cast<std::size_t>(n);
  }
  EXPECT_TRUE(sink.drain(2'000'000'000));
  sink.close();
  EXPECT_EQ(sink.stripes_written(), 20u);
  EXPECT_EQ(sink.stripes_delivered(), 20u);
  EXPECT_EQ(sink.stripes_lost_in_flight(), 0u);
  EXPECT_EQ(sink.last_error(), "");
  close(c);
}

TEST(TcpSink, HostThatNeverReadsDoesNotGetEveryStripe) {
  Listener l;
  TcpSink sink(l.address(), fast());
  const int c = l.accept_within(3000);
  ASSERT_GE(c, 0);
  // 8 MB of stripes: more than the socket buffers on both sides hold.
  const std::uint32_t n = static_cast<std::uint32_t>((8u << 20) / stripe_frame(0).size()) + 1;
  for (std::uint32_t i = 0; i < n; ++i) sink.write(stripe_frame(i));
  EXPECT_FALSE(sink.drain(300'000'000));
  sink.close();
  EXPECT_EQ(sink.stripes_written(), n);
  EXPECT_LT(sink.stripes_delivered(), n);
  EXPECT_GT(sink.buffered_bytes(), 0u);
  close(c);
}

TEST(TcpSink, NamesTheLinkError) {
  {  // nothing listens on the port: connection refused, naming HOST:PORT
    std::uint16_t port = 0;
    {
      Listener l;
      port = l.port;
    }
    const std::string addr = "127.0.0.1:" + std::to_string(port);
    TcpSink sink(addr, fast());
    sink.write(stripe_frame(0));
    EXPECT_TRUE(eventually([&] { return !sink.last_error().empty(); }));
    sink.close();
    EXPECT_EQ(sink.last_error(), "cannot connect to " + addr + ": Connection refused");
    EXPECT_EQ(sink.stripes_delivered(), 0u);
    EXPECT_EQ(sink.stripes_written(), 1u);
  }
  {  // a name that does not resolve (RFC 6761: .invalid never does): the resolver's message, naming the host
    EXPECT_EQ(resolve_error("127.0.0.1", 5555), "");
    const std::string e = resolve_error("nosuchhost.invalid", 5555);
    EXPECT_EQ(e.rfind("cannot resolve host 'nosuchhost.invalid': ", 0), 0u) << e;
    TcpSink sink("nosuchhost.invalid:5555", fast());
    EXPECT_TRUE(eventually([&] { return !sink.last_error().empty(); }));
    sink.close();
    EXPECT_EQ(sink.last_error().rfind("cannot resolve host 'nosuchhost.invalid': ", 0), 0u)
        << sink.last_error();
  }
  {  // the host hangs up: the loss is named
    Listener l;
    TcpSink sink(l.address(), fast());
    const int c = l.accept_within(3000);
    ASSERT_GE(c, 0);
    close(c);
    EXPECT_TRUE(eventually([&] { return !sink.last_error().empty(); }));
    sink.close();
    EXPECT_EQ(sink.last_error().rfind("connection to " + l.address() + " lost: ", 0), 0u)
        << sink.last_error();
  }
}

TEST(TcpSink, RejectsBadAddress) {
  std::string h;
  std::uint16_t p = 0;
  EXPECT_THROW(parse_host_port("localhost", h, p), fs::Error);
  EXPECT_THROW(parse_host_port("localhost:0", h, p), fs::Error);
  EXPECT_THROW(parse_host_port("localhost:99999", h, p), fs::Error);
  parse_host_port("[::1]:5555", h, p);
  EXPECT_EQ(h, "::1");
  EXPECT_EQ(p, 5555);
}

}  // namespace
}  // namespace fs::fw
