// Live stream server: scans over TCP (complete, disconnect -> partial, reconnect continues the scan,
// grace expiry, link timeout, protocol errors, byte-by-byte chunking), heartbeats to the scanner.
// Timeouts use an injected clock; the loop only waits for socket events.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include "common/error.hpp"
#include "common/wire.hpp"
#include "host/io/stream_server.hpp"
#include "synth_scan.hpp"

namespace fs::host {
namespace {

struct FakeClock {
  std::int64_t t = 1'000'000'000;
  std::function<std::int64_t()> fn() {
    return [this] { return t; };
  }
};

int connect_to(std::uint16_t port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(port);
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

void send_all(int fd, std::span<const std::uint8_t> bytes, std::size_t chunk = 1 << 20) {
  while (!bytes.empty()) {
    const std::size_t n = std::min(chunk, bytes.size());
    const ssize_t r = ::send(fd, bytes.data(), n, MSG_NOSIGNAL);
    ASSERT_GT(r, 0);
    bytes = bytes.subspan(static_cast<std::size_t>(r));
  }
}

// Frames of a synthetic scan: [begin, stripes[from, to), end?].
std::vector<std::uint8_t> frames(const fs::test::SynthScan& s, bool begin, std::size_t from, std::size_t to,
                                 bool end, std::uint32_t seq = 0) {
  wire::VectorSink sink;
  wire::FrameWriter w(sink, seq);
  if (begin) w.send(s.begin);
  for (std::size_t i = from; i < to; ++i) {
    msg::Stripe m;
    m.header = s.stripes[i].header;
    m.points = std::span<msg::StripePoint>(const_cast<msg::StripePoint*>(s.stripes[i].points.data()),
                                           s.stripes[i].points.size());
    w.send(m);
  }
  msg::Heartbeat hb;
  w.send(hb);
  if (end) w.send(s.end);
  return sink.data;
}

class StreamTest : public ::testing::Test {
 protected:
  void SetUp() override {
    calib = ScannerCalibration::bench_default(30);
    synth = fs::test::synth_flat_scan(calib, calib, 12.0, 0.0, 1, 42, 32);
  }
  std::unique_ptr<StreamServer> make(std::int64_t grace_ms) {
    StreamServerOptions o;
    o.listen = "127.0.0.1:0";
    o.reconnect_grace_ms = grace_ms;
    o.link_timeout_ms = 3000;
    o.heartbeat_interval_ms = 500;
    o.now_ns = clock.fn();
    auto s = std::make_unique<StreamServer>(o, [this](const Scan& sc) {
      statuses.push_back(sc.status());
      stripe_counts.push_back(sc.stripes_received());
    });
    s->start();
    EXPECT_NE(s->port(), 0);
    return s;
  }
  template <typename P>
  bool pump(StreamServer& s, P pred) {
    for (int i = 0; i < 1000 && !pred(); ++i) s.poll_once(10);
    return pred();
  }
  ScannerCalibration calib;
  fs::test::SynthScan synth;
  FakeClock clock;
  std::vector<ScanStatus> statuses;
  std::vector<std::uint32_t> stripe_counts;
};

TEST_F(StreamTest, CompleteScanAndHeartbeatsToScanner) {
  auto server = make(5000);
  const int fd = connect_to(server->port());
  ASSERT_GE(fd, 0);
  ASSERT_TRUE(pump(*server, [&] { return server->connected(); }));
  const auto bytes = frames(synth, true, 0, 30, true);
  send_all(fd, bytes, 7);  // odd chunking: frames split across reads
  ASSERT_TRUE(pump(*server, [&] { return !statuses.empty(); }));
  EXPECT_EQ(statuses[0], ScanStatus::Complete);
  EXPECT_EQ(stripe_counts[0], 30u);
  EXPECT_EQ(server->stats().frames, 33u);
  EXPECT_EQ(server->assembler_stats().heartbeats, 1u);
  // The server greeted the scanner with a heartbeat and sends more as the (fake) clock advances.
  clock.t += 600'000'000;
  server->poll_once(0);
  EXPECT_EQ(server->stats().heartbeats_sent, 2u);
  std::uint8_t buf[256];
  std::size_t got = 0;
  while (got < 2 * (wire::kFrameOverhead + wire::kHeartbeatSize)) {
    const ssize_t r = ::recv(fd, buf + got, sizeof(buf) - got, 0);
    ASSERT_GT(r, 0);
    got += static_cast<std::size_t>(r);
  }
  wire::FrameDecoder dec("from host");
  dec.feed(std::span<const std::uint8_t>(buf, got));
  wire::FrameView f;
  int hbs = 0;
  while (dec.next(f)) hbs += f.header.type == msg::Type::Heartbeat ? 1 : 0;
  EXPECT_EQ(hbs, 2);
  ::close(fd);
}

TEST_F(StreamTest, DisconnectMidScanYieldsPartialScan) {
  auto server = make(0);
  const int fd = connect_to(server->port());
  ASSERT_TRUE(pump(*server, [&] { return server->connected(); }));
  send_all(fd, frames(synth, true, 0, 12, false));
  ASSERT_TRUE(pump(*server, [&] { return server->stats().frames >= 14; }));
  ::close(fd);
  ASSERT_TRUE(pump(*server, [&] { return !statuses.empty(); }));
  EXPECT_EQ(statuses[0], ScanStatus::Disconnected);
  EXPECT_EQ(stripe_counts[0], 12u);
  EXPECT_EQ(server->stats().disconnects, 1u);
}

TEST_F(StreamTest, ReconnectWithinGraceContinuesTheScan) {
  auto server = make(5000);
  int fd = connect_to(server->port());
  ASSERT_TRUE(pump(*server, [&] { return server->connected(); }));
  const auto first = frames(synth, true, 0, 10, false);
  // Cut the connection in the middle of a frame: the scanner resends that frame whole.
  send_all(fd, std::span(first).first(first.size() - 40));
  ASSERT_TRUE(pump(*server, [&] { return server->stats().bytes >= first.size() - 40; }));
  ::close(fd);
  ASSERT_TRUE(pump(*server, [&] { return !server->connected(); }));
  clock.t += 1'000'000'000;  // 1 s later, within the grace
  server->poll_once(0);
  EXPECT_TRUE(statuses.empty());
  fd = connect_to(server->port());
  ASSERT_TRUE(pump(*server, [&] { return server->connected(); }));
  send_all(fd, frames(synth, false, 9, 30, true, 100));
  ASSERT_TRUE(pump(*server, [&] { return !statuses.empty(); }));
  EXPECT_EQ(statuses[0], ScanStatus::Complete);
  EXPECT_EQ(stripe_counts[0], 30u);
  EXPECT_EQ(server->stats().connections, 2u);
  ::close(fd);
}

TEST_F(StreamTest, GraceExpiryDeliversPartialAndNewConnectionReplacesOld) {
  auto server = make(2000);
  const int fd = connect_to(server->port());
  ASSERT_TRUE(pump(*server, [&] { return server->connected(); }));
  send_all(fd, frames(synth, true, 0, 5, false));
  ASSERT_TRUE(pump(*server, [&] { return server->stats().frames >= 7; }));
  // A second connection replaces the first (scanner re-dialled); the scan stays open.
  const int fd2 = connect_to(server->port());
  ASSERT_TRUE(pump(*server, [&] { return server->stats().connections == 2; }));
  EXPECT_TRUE(statuses.empty());
  ::close(fd2);
  ASSERT_TRUE(pump(*server, [&] { return !server->connected(); }));
  clock.t += 2'500'000'000;
  server->poll_once(0);
  ASSERT_EQ(statuses.size(), 1u);
  EXPECT_EQ(statuses[0], ScanStatus::Disconnected);
  EXPECT_EQ(stripe_counts[0], 5u);
  ::close(fd);
}

TEST_F(StreamTest, SilentLinkTimesOutAndGarbageIsAProtocolError) {
  auto server = make(0);
  int fd = connect_to(server->port());
  ASSERT_TRUE(pump(*server, [&] { return server->connected(); }));
  send_all(fd, frames(synth, true, 0, 3, false));
  ASSERT_TRUE(pump(*server, [&] { return server->stats().frames >= 5; }));
  clock.t += 3'500'000'000;
  server->poll_once(0);
  EXPECT_FALSE(server->connected());
  EXPECT_EQ(server->stats().link_timeouts, 1u);
  ASSERT_EQ(statuses.size(), 1u);
  EXPECT_EQ(statuses[0], ScanStatus::Disconnected);
  ::close(fd);

  fd = connect_to(server->port());
  ASSERT_TRUE(pump(*server, [&] { return server->connected(); }));
  std::vector<std::uint8_t> junk(64, 0x41);
  send_all(fd, junk);
  ASSERT_TRUE(pump(*server, [&] { return server->stats().protocol_errors == 1; }));
  EXPECT_FALSE(server->connected());
  EXPECT_NE(server->stats().last_error.find("at byte"), std::string::npos) << server->stats().last_error;
  ::close(fd);
}

// A bad CRC mid-scan is a protocol error naming the peer (counted, reported through on_protocol_error); the
// cut scan, not resumed, ends as ProtocolError when the next scan begins, not as Superseded.
TEST_F(StreamTest, ProtocolErrorNamesThePeerAndIsNotSuperseded) {
  std::vector<std::string> logged;
  StreamServerOptions o;
  o.listen = "127.0.0.1:0";
  o.reconnect_grace_ms = 5000;
  o.now_ns = clock.fn();
  o.on_protocol_error = [&](const std::string& peer, const std::string& reason) {
    logged.push_back(peer + " " + reason);
  };
  StreamServer server(o, [this](const Scan& sc) { statuses.push_back(sc.status()); });
  server.start();
  int fd = connect_to(server.port());
  ASSERT_TRUE(pump(server, [&] { return server.connected(); }));
  auto bytes = frames(synth, true, 0, 10, false);
  bytes[bytes.size() - 30] ^= 0x5a;  // inside the last frames: a CRC mismatch
  send_all(fd, bytes);
  ASSERT_TRUE(pump(server, [&] { return server.stats().protocol_errors == 1; }));
  EXPECT_FALSE(server.connected());
  EXPECT_NE(server.stats().last_error.find("protocol error from 127.0.0.1:"), std::string::npos)
      << server.stats().last_error;
  ASSERT_EQ(logged.size(), 1u);
  EXPECT_EQ(logged[0].rfind("127.0.0.1:", 0), 0u) << logged[0];
  EXPECT_TRUE(statuses.empty());  // within the grace the scanner may still resume it
  ::close(fd);
  fd = connect_to(server.port());
  ASSERT_TRUE(pump(server, [&] { return server.connected(); }));
  send_all(fd, frames(synth, true, 0, 30, true, 200));  // a new scan instead
  ASSERT_TRUE(pump(server, [&] { return statuses.size() == 2; }));
  EXPECT_EQ(statuses[0], ScanStatus::ProtocolError);
  EXPECT_STREQ(to_string(statuses[0]), "connection closed for a protocol error");
  EXPECT_EQ(statuses[1], ScanStatus::Complete);
  EXPECT_EQ(server.stats().protocol_errors, 1u);
  ::close(fd);
}

// A scan the callback fails to process is not a protocol error: the connection stays, the next scan on it is
// delivered, the error is counted and the server keeps serving.
TEST_F(StreamTest, ProcessingErrorKeepsTheConnection) {
  StreamServerOptions o;
  o.listen = "127.0.0.1:0";
  o.now_ns = clock.fn();
  int calls = 0;
  StreamServer server(o, [&](const Scan& sc) {
    statuses.push_back(sc.status());
    if (++calls == 1) throw Error("graph: 515 nodes, the matcher handles at most 128");
  });
  server.start();
  const int fd = connect_to(server.port());
  ASSERT_TRUE(pump(server, [&] { return server.connected(); }));
  auto bytes = frames(synth, true, 0, 30, true);
  const auto again = frames(synth, true, 0, 30, true, 100);
  bytes.insert(bytes.end(), again.begin(), again.end());
  send_all(fd, bytes);
  ASSERT_TRUE(pump(server, [&] { return statuses.size() == 2; }));
  EXPECT_EQ(statuses[0], ScanStatus::Complete);
  EXPECT_EQ(statuses[1], ScanStatus::Complete);
  EXPECT_TRUE(server.connected());
  EXPECT_EQ(server.stats().protocol_errors, 0u);
  EXPECT_EQ(server.stats().disconnects, 0u);
  EXPECT_EQ(server.stats().scan_errors, 1u);
  EXPECT_NE(server.stats().last_scan_error.find("515 nodes"), std::string::npos);
  ::close(fd);
}

TEST(StreamServerAddress, ParsesAndRejects) {
  std::string host;
  std::uint16_t port = 0;
  parse_listen_address("127.0.0.1:5555", host, port);
  EXPECT_EQ(host, "127.0.0.1");
  EXPECT_EQ(port, 5555);
  parse_listen_address("[::1]:0", host, port);
  EXPECT_EQ(host, "::1");
  EXPECT_THROW(parse_listen_address("localhost", host, port), fs::Error);
  EXPECT_THROW(parse_listen_address("a:70000", host, port), fs::Error);
  StreamServerOptions o;
  o.listen = "256.1.1.1:0";
  StreamServer s(o, [](const Scan&) {});
  EXPECT_THROW(s.start(), fs::Error);
}

}  // namespace
}  // namespace fs::host
