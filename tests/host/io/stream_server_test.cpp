// Live stream server: scans over TCP (complete, disconnect -> partial, reconnect continues the scan,
// grace expiry, link timeout, protocol errors, byte-by-byte chunking), heartbeats to the scanner, several
// connections (probes, a second scanner waiting, a resuming re-dial, the connection limit), back-pressure,
// ScanBegins refused by the memory budget, the bounded hand-off queue.
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

TEST_F(StreamTest, TheScanInProgressIsForwardedFrameByFrame) {
  // serve --nats --stream forwards what the assembler takes for the scan in progress: its ScanBegin and its
  // stripes, not heartbeats, not the ScanEnd (the scan callback follows it), not stripes of another scan.
  StreamServerOptions o;
  o.listen = "127.0.0.1:0";
  o.now_ns = clock.fn();
  std::vector<std::pair<msg::Type, std::uint64_t>> forwarded;  // type, scan id
  std::size_t forwarded_at_delivery = 0;
  o.on_scan_frame = [&](const std::string& peer, const wire::DecodedMessage& m) {
    EXPECT_NE(peer.find("127.0.0.1:"), std::string::npos);
    forwarded.emplace_back(m.type,
                           m.type == msg::Type::ScanBegin ? m.scan_begin.scan_id : m.stripe.header.scan_id);
  };
  StreamServer server(o, [&](const Scan& sc) {
    statuses.push_back(sc.status());
    forwarded_at_delivery = forwarded.size();
  });
  server.start();
  const int fd = connect_to(server.port());
  ASSERT_GE(fd, 0);
  fs::test::SynthScan other = synth;  // a stripe of scan 99: an orphan
  for (auto& st : other.stripes) st.header.scan_id = 99;
  std::vector<std::uint8_t> bytes = frames(other, false, 0, 1, false);
  const auto scan = frames(synth, true, 0, 10, true, 2);
  bytes.insert(bytes.end(), scan.begin(), scan.end());
  const auto late = frames(synth, false, 10, 11, false, 15);  // after the ScanEnd: an orphan too
  bytes.insert(bytes.end(), late.begin(), late.end());
  send_all(fd, bytes, 5);
  ASSERT_TRUE(pump(server, [&] { return !statuses.empty() && server.stats().frames == 17u; }));
  EXPECT_EQ(statuses.size(), 1u);  // 10 of its stripes: delivered as missing stripes
  ASSERT_EQ(forwarded.size(), 11u);
  EXPECT_EQ(forwarded_at_delivery, 11u);  // every stripe reached the hook before the scan was delivered
  EXPECT_EQ(forwarded[0], std::make_pair(msg::Type::ScanBegin, synth.begin.scan_id));
  for (std::size_t i = 1; i < forwarded.size(); ++i)
    EXPECT_EQ(forwarded[i], std::make_pair(msg::Type::Stripe, synth.begin.scan_id)) << i;
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

TEST_F(StreamTest, GraceExpiryDeliversPartialAndAnIdleConnectionDoesNotEvictTheScanner) {
  auto server = make(2000);
  const int fd = connect_to(server->port());
  ASSERT_TRUE(pump(*server, [&] { return server->connected(); }));
  send_all(fd, frames(synth, true, 0, 5, false));
  ASSERT_TRUE(pump(*server, [&] { return server->stats().frames >= 7; }));
  // A second connection (a probe) is accepted and read; the scanner keeps its connection and its scan.
  const int fd2 = connect_to(server->port());
  ASSERT_TRUE(pump(*server, [&] { return server->connection_count() == 2; }));
  EXPECT_EQ(server->stats().connections, 2u);
  send_all(fd, frames(synth, false, 5, 8, false, 100));
  ASSERT_TRUE(pump(*server, [&] { return server->current_scan().stripes_received() == 8; }));
  EXPECT_TRUE(server->scanner_connected());
  EXPECT_TRUE(statuses.empty());
  ::close(fd2);
  ASSERT_TRUE(pump(*server, [&] { return server->connection_count() == 1; }));
  // The scanner goes away: the scan waits for the grace, then is delivered as partial.
  ::close(fd);
  ASSERT_TRUE(pump(*server, [&] { return !server->connected(); }));
  clock.t += 1'000'000'000;
  server->poll_once(0);
  EXPECT_TRUE(statuses.empty());
  clock.t += 1'500'000'000;
  server->poll_once(0);
  ASSERT_EQ(statuses.size(), 1u);
  EXPECT_EQ(statuses[0], ScanStatus::Disconnected);
  EXPECT_EQ(stripe_counts[0], 8u);
  EXPECT_EQ(server->stats().disconnects, 2u);
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

// ---- several connections (issue #25 item 5), back-pressure, refused ScanBegins

// The synthetic scan under another scan id.
fs::test::SynthScan with_id(fs::test::SynthScan s, std::uint64_t id) {
  s.begin.scan_id = id;
  for (auto& st : s.stripes) st.header.scan_id = id;
  s.end.scan_id = id;
  return s;
}

// A scanner streams 8 scans while another client connects every 50 ms (injected clock) and stays silent:
// every scan arrives complete, the scanner's connection is never closed, the probes are closed (room for
// newer ones, then the link timeout) without disturbing it.
TEST_F(StreamTest, ScannerStreamsEightScansWhileAnotherClientConnectsEvery50ms) {
  auto server = make(5000);
  const int scanner = connect_to(server->port());
  ASSERT_TRUE(pump(*server, [&] { return server->connected(); }));
  std::vector<int> probes;
  std::uint32_t seq = 0;
  for (std::uint64_t id = 1; id <= 8; ++id) {
    const auto scan = with_id(synth, id);
    for (std::size_t from = 0; from < 30; from += 5) {
      send_all(scanner, frames(scan, from == 0, from, from + 5, from + 5 == 30, seq));
      seq += 10;
      const std::uint64_t conns = server->stats().connections;
      probes.push_back(connect_to(server->port()));
      ASSERT_TRUE(pump(*server, [&] { return server->stats().connections == conns + 1; }));
      clock.t += 50'000'000;  // 50 ms between probes
      server->poll_once(0);
    }
    ASSERT_TRUE(pump(*server, [&] { return statuses.size() == id; })) << "scan " << id;
  }
  ASSERT_EQ(statuses.size(), 8u);
  for (std::size_t i = 0; i < 8; ++i) {
    EXPECT_EQ(statuses[i], ScanStatus::Complete) << i;
    EXPECT_EQ(stripe_counts[i], 30u) << i;
  }
  EXPECT_TRUE(server->scanner_connected());
  EXPECT_EQ(server->stats().connections, 49u);
  // 48 probes, at most max_clients - 1 open at a time beside the scanner: the older ones were closed for
  // room (idle) or timed out (48 x 50 ms > the 3 s link timeout).
  EXPECT_LE(server->connection_count(), 4u);
  EXPECT_EQ(server->stats().idle_closed + server->stats().link_timeouts + server->connection_count() - 1,
            48u);
  EXPECT_GT(server->stats().idle_closed, 0u);
  EXPECT_EQ(server->stats().refused_connections, 0u);
  EXPECT_EQ(server->assembler_stats().orphan_stripes, 0u);
  ::close(scanner);
  for (int fd : probes) ::close(fd);
}

// A second scanner starting a scan while the first streams waits (not read further) until the first scan is
// delivered, then streams its own: both complete, nothing superseded or evicted.
TEST_F(StreamTest, ASecondScannerWaitsForTheScanInProgress) {
  std::vector<std::string> notices;
  StreamServerOptions o;
  o.listen = "127.0.0.1:0";
  o.now_ns = clock.fn();
  o.on_notice = [&](const std::string& peer, const std::string& what) {
    notices.push_back(peer + " " + what);
  };
  std::vector<std::uint64_t> ids;
  StreamServer server(o, [&](const Scan& sc) {
    statuses.push_back(sc.status());
    stripe_counts.push_back(sc.stripes_received());
    ids.push_back(sc.scan_id());
  });
  server.start();
  const auto a = with_id(synth, 10), b = with_id(synth, 20);
  const int fa = connect_to(server.port());
  ASSERT_TRUE(pump(server, [&] { return server.connected(); }));
  send_all(fa, frames(a, true, 0, 10, false));
  ASSERT_TRUE(pump(server, [&] { return server.current_scan().stripes_received() == 10; }));
  const int fb = connect_to(server.port());
  send_all(fb, frames(b, true, 0, 30, true));
  ASSERT_TRUE(pump(server, [&] { return server.stats().waited_scans == 1; }));
  ASSERT_EQ(notices.size(), 1u);
  EXPECT_NE(notices[0].find("scan 20 waits: scan 10 streams from 127.0.0.1:"), std::string::npos)
      << notices[0];
  // Held past the link timeout: the pause is ours, the waiting connection is not timed out.
  for (int i = 0; i < 8; ++i) {
    clock.t += 500'000'000;
    send_all(fa, frames(a, false, 10, 10, false, 100 + i));  // the first scanner's heartbeats
    server.poll_once(5);
  }
  EXPECT_EQ(server.stats().link_timeouts, 0u);
  EXPECT_EQ(server.current_scan().scan_id(), 10u);
  send_all(fa, frames(a, false, 10, 30, true, 200));
  ASSERT_TRUE(pump(server, [&] { return statuses.size() == 2; }));
  EXPECT_EQ(ids, (std::vector<std::uint64_t>{10, 20}));
  EXPECT_EQ(statuses[0], ScanStatus::Complete);
  EXPECT_EQ(statuses[1], ScanStatus::Complete);
  EXPECT_EQ(stripe_counts[1], 30u);
  EXPECT_EQ(server.stats().disconnects, 0u);
  EXPECT_EQ(server.connection_count(), 2u);
  ::close(fa);
  ::close(fb);
}

// The scanner re-dials while its old connection still looks alive (half-open): the new connection resends
// stripes of the scan in progress, takes the scan over (duplicates counted) and the old one is closed.
TEST_F(StreamTest, ANewConnectionResumingTheScanTakesItOver) {
  std::vector<int> duplicates;
  StreamServerOptions o;
  o.listen = "127.0.0.1:0";
  o.now_ns = clock.fn();
  StreamServer server(o, [&](const Scan& sc) {
    statuses.push_back(sc.status());
    stripe_counts.push_back(sc.stripes_received());
    duplicates.push_back(static_cast<int>(sc.duplicate_stripes()));
  });
  server.start();
  const int old_fd = connect_to(server.port());
  ASSERT_TRUE(pump(server, [&] { return server.connected(); }));
  send_all(old_fd, frames(synth, true, 0, 12, false));
  ASSERT_TRUE(pump(server, [&] { return server.current_scan().stripes_received() == 12; }));
  const int new_fd = connect_to(server.port());
  send_all(new_fd, frames(synth, false, 8, 30, true, 50));  // 8..11 again
  ASSERT_TRUE(pump(server, [&] { return statuses.size() == 1; }));
  EXPECT_EQ(statuses[0], ScanStatus::Complete);
  EXPECT_EQ(stripe_counts[0], 30u);
  EXPECT_EQ(duplicates[0], 4);
  EXPECT_EQ(server.stats().resumed, 1u);
  EXPECT_EQ(server.connection_count(), 1u);  // the old connection was closed
  ::close(old_fd);
  ::close(new_fd);
}

// max_clients: at the limit a new connection takes the place of one that never sent a frame; when all of them
// stream, it is refused. Both are logged.
TEST_F(StreamTest, ConnectionLimitClosesIdleThenRefuses) {
  std::vector<std::string> notices;
  StreamServerOptions o;
  o.listen = "127.0.0.1:0";
  o.now_ns = clock.fn();
  o.max_clients = 2;
  o.on_notice = [&](const std::string& peer, const std::string& what) {
    notices.push_back(peer + " " + what);
  };
  StreamServer server(o, [&](const Scan& sc) { statuses.push_back(sc.status()); });
  server.start();
  const int s1 = connect_to(server.port());
  ASSERT_TRUE(pump(server, [&] { return server.connection_count() == 1; }));
  send_all(s1, frames(synth, true, 0, 3, false));
  ASSERT_TRUE(pump(server, [&] { return server.stats().frames >= 4; }));
  const int idle = connect_to(server.port());
  ASSERT_TRUE(pump(server, [&] { return server.connection_count() == 2; }));
  const int s2 = connect_to(server.port());  // takes the idle one's place
  ASSERT_TRUE(pump(server, [&] { return server.stats().idle_closed == 1; }));
  EXPECT_EQ(server.connection_count(), 2u);
  msg::Heartbeat hb;
  wire::VectorSink sink;
  wire::FrameWriter(sink).send(hb);
  send_all(s2, sink.data);
  ASSERT_TRUE(pump(server, [&] { return server.assembler_stats().heartbeats == 2; }));
  const int s3 = connect_to(server.port());  // both open connections have sent frames: refused
  ASSERT_TRUE(pump(server, [&] { return server.stats().refused_connections == 1; }));
  EXPECT_EQ(server.connection_count(), 2u);
  ASSERT_EQ(notices.size(), 2u);
  EXPECT_NE(notices[0].find("it sent nothing"), std::string::npos) << notices[0];
  EXPECT_NE(notices[1].find("connection refused: 2 connections are open"), std::string::npos) << notices[1];
  EXPECT_TRUE(statuses.empty());  // the scan streams on
  for (int fd : {s1, idle, s2, s3}) ::close(fd);
}

// Back-pressure: while the consumer has no room, the ScanEnd that would deliver a scan is held with the rest
// of the stream; heartbeats go on and the link is not timed out for the pause; with room again the scan is
// delivered and the next one streams.
TEST_F(StreamTest, BackPressureHoldsTheDeliveryNotTheLink) {
  bool room = false;
  StreamServerOptions o;
  o.listen = "127.0.0.1:0";
  o.now_ns = clock.fn();
  o.can_deliver = [&] { return room; };
  StreamServer server(o, [&](const Scan& sc) {
    statuses.push_back(sc.status());
    stripe_counts.push_back(sc.stripes_received());
  });
  server.start();
  const int fd = connect_to(server.port());
  ASSERT_TRUE(pump(server, [&] { return server.connected(); }));
  room = true;  // a ScanBegin needs room too (it may supersede or be refused: both deliver)
  send_all(fd, frames(synth, true, 0, 30, false));
  ASSERT_TRUE(pump(server, [&] { return server.current_scan().stripes_received() == 30; }));
  room = false;
  auto bytes = frames(synth, false, 30, 30, true, 50);
  const auto next = frames(with_id(synth, 2), true, 0, 30, true, 100);
  bytes.insert(bytes.end(), next.begin(), next.end());
  send_all(fd, bytes);
  ASSERT_TRUE(pump(server, [&] { return server.stats().held_for_queue > 0; }));
  const std::uint64_t hb0 = server.stats().heartbeats_sent;
  for (int i = 0; i < 10; ++i) {  // 5 s of fake time, beyond the 3 s link timeout
    clock.t += 500'000'000;
    server.poll_once(1);
  }
  EXPECT_TRUE(statuses.empty());
  EXPECT_TRUE(server.connected());
  EXPECT_EQ(server.stats().link_timeouts, 0u);
  EXPECT_GE(server.stats().heartbeats_sent, hb0 + 10);
  room = true;
  server.wake();
  ASSERT_TRUE(pump(server, [&] { return statuses.size() == 2; }));
  EXPECT_EQ(statuses[0], ScanStatus::Complete);
  EXPECT_EQ(statuses[1], ScanStatus::Complete);
  EXPECT_EQ(stripe_counts[1], 30u);
  ::close(fd);
}

// A ScanBegin beyond the memory budget is refused: told through on_refused with the reason, not a protocol
// error; the connection stays, the refused scan's stripes are orphans and the next scan is delivered.
TEST_F(StreamTest, ARefusedScanBeginIsReportedAndTheConnectionStays) {
  std::vector<std::string> refusals;
  StreamServerOptions o;
  o.listen = "127.0.0.1:0";
  o.now_ns = clock.fn();
  o.limits = ScanLimits::for_budget(std::uint64_t(256) << 20);
  o.on_refused = [&](const std::string& peer, const msg::ScanBegin& b, const std::string& reason) {
    refusals.push_back(peer + " " + std::to_string(b.scan_id) + " " + reason);
  };
  StreamServer server(o, [&](const Scan& sc) { statuses.push_back(sc.status()); });
  server.start();
  auto big = with_id(synth, 7);
  big.begin.calibration.camera.width = 16384;
  big.begin.calibration.camera.height = 16384;  // a 268 M-entry ray table
  const int fd = connect_to(server.port());
  ASSERT_TRUE(pump(server, [&] { return server.connected(); }));
  auto bytes = frames(big, true, 0, 30, true);
  const auto good = frames(synth, true, 0, 30, true, 100);
  bytes.insert(bytes.end(), good.begin(), good.end());
  send_all(fd, bytes);
  ASSERT_TRUE(pump(server, [&] { return statuses.size() == 1; }));
  EXPECT_EQ(statuses[0], ScanStatus::Complete);
  ASSERT_EQ(refusals.size(), 1u);
  EXPECT_EQ(refusals[0].rfind("127.0.0.1:", 0), 0u) << refusals[0];
  EXPECT_NE(refusals[0].find(" 7 ScanBegin of scan 7: camera 16384 x 16384"), std::string::npos)
      << refusals[0];
  EXPECT_NE(refusals[0].find("memory budget of 256 MiB"), std::string::npos) << refusals[0];
  EXPECT_EQ(server.stats().refused_scans, 1u);
  EXPECT_EQ(server.stats().protocol_errors, 0u);
  EXPECT_TRUE(server.connected());
  EXPECT_EQ(server.assembler_stats().orphan_stripes, 31u);  // its 30 stripes and its ScanEnd
  ::close(fd);
}

TEST(ScanQueue, BoundedByJobsAndBytesAndAnEmptyQueueTakesOne) {
  ScanQueue q(2, 1000);
  EXPECT_TRUE(q.has_room());
  ScanJob big;
  big.bytes = 5000;  // above the byte bound alone: an empty queue still takes it
  q.push(std::move(big));
  EXPECT_FALSE(q.has_room());
  ScanJob out;
  ASSERT_TRUE(q.pop(out));
  EXPECT_EQ(out.bytes, 5000u);
  EXPECT_EQ(q.bytes(), 0u);
  for (int i = 0; i < 2; ++i) {
    ScanJob j;
    j.bytes = 10;
    q.push(std::move(j));
  }
  EXPECT_FALSE(q.has_room());  // two jobs
  q.close();
  EXPECT_TRUE(q.pop(out));  // what was queued is still handed out after close()
  EXPECT_TRUE(q.pop(out));
  EXPECT_FALSE(q.pop(out));
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
