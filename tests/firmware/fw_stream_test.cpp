// facetscan-fw-hil run as a user runs it, streaming to hosts that do not take the stream (nothing listening,
// a name that does not resolve, a host that accepts and never reads) and to one that reads everything: the
// exit status (4 = stripes undelivered), the summary's "N of M stripes undelivered" with the link error, the
// recording's final ScanEnd.stripes_dropped and Fault 102; and the laser-off latency of a fault in the
// summary and in the recorded Fault message.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "common/scan_file.hpp"
#include "common/wire.hpp"
#include "support/run_command.hpp"
#include "support/test_paths.hpp"

namespace fs::test {
namespace {

namespace stdfs = std::filesystem;

std::string hil() {
  return (bin_dir() / "facetscan-fw-hil").string() + " --scene " +
         (source_dir() / "hw-sim/scenes/cube.json").string();
}

// A scratch directory per process, removed at exit.
struct ScratchDir {
  ScratchDir() : path(stdfs::temp_directory_path() / ("facetscan-fwstream-" + std::to_string(getpid()))) {}
  ~ScratchDir() {
    std::error_code ec;
    stdfs::remove_all(path, ec);
  }
  stdfs::path path;
};

stdfs::path temp_path(const std::string& name) {
  static ScratchDir dir;
  stdfs::create_directories(dir.path);
  return dir.path / name;
}

// A listening socket on 127.0.0.1 (ephemeral port); rcvbuf > 0 shrinks its receive buffer (set before
// listen, inherited by the accepted socket).
struct Listener {
  explicit Listener(int rcvbuf = 0) {
    fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (rcvbuf > 0) setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    socklen_t len = sizeof a;
    getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
    port = ntohs(a.sin_port);
    EXPECT_EQ(listen(fd, 4), 0);
  }
  ~Listener() {
    if (fd >= 0) close(fd);
  }
  std::string address() const { return "127.0.0.1:" + std::to_string(port); }
  int fd = -1;
  std::uint16_t port = 0;
};

// A port on 127.0.0.1 where nothing listens: bound, then closed.
std::string closed_port() {
  Listener l;
  const std::string a = l.address();
  close(l.fd);
  l.fd = -1;
  return a;
}

struct Recording {
  std::vector<msg::Fault> faults;
  std::vector<msg::ScanEnd> ends;
  std::uint32_t stripes = 0;
};

Recording read_recording(const stdfs::path& p) {
  Recording r;
  ScanFileReader reader(p);
  wire::DecodedMessage m;
  while (reader.next(m)) {
    if (m.type == msg::Type::Fault) r.faults.push_back(m.fault);
    if (m.type == msg::Type::ScanEnd) r.ends.push_back(m.scan_end);
    if (m.type == msg::Type::Stripe) ++r.stripes;
  }
  return r;
}

// "N of M stripes undelivered to ADDR: ERROR" from the summary.
struct Undelivered {
  bool found = false;
  unsigned n = 0, m = 0;
  std::string error;
};
// (No std::regex: GCC 12 reports a false maybe-uninitialized in it at -O1, the sanitizer build.)
Undelivered undelivered_line(const std::string& out) {
  Undelivered u;
  const std::string tag = " stripes undelivered to ";
  const std::size_t at = out.find(tag);
  if (at == std::string::npos) return u;
  const std::size_t line = out.rfind("error: ", at);
  if (line == std::string::npos) return u;
  unsigned n = 0, m = 0;
  if (std::sscanf(out.c_str() + line, "error: %u of %u stripes undelivered to ", &n, &m) != 2) return u;
  const std::size_t colon = out.find(": ", at + tag.size());
  const std::size_t eol = out.find('\n', at);
  if (colon == std::string::npos || colon > eol) return u;
  u.found = true;
  u.n = n;
  u.m = m;
  u.error = out.substr(colon + 2, eol == std::string::npos ? std::string::npos : eol - colon - 2);
  return u;
}

// The recording's final ScanEnd carries the undelivered count; a Fault 102 says the same.
void expect_recorded_count(const stdfs::path& rec, unsigned n, unsigned m) {
  const Recording r = read_recording(rec);
  EXPECT_EQ(r.stripes, m);  // the recording itself has every stripe
  ASSERT_EQ(r.ends.size(), 1u);
  EXPECT_EQ(r.ends[0].stripes_dropped, n);
  EXPECT_EQ(r.ends[0].completed, 1);
  bool found = false;
  const std::string want = std::to_string(n) + " of " + std::to_string(m) + " stripes undelivered";
  for (const auto& f : r.faults) found = found || (f.code == 102 && f.text.find(want) != std::string::npos);
  EXPECT_TRUE(found) << "no Fault 102 '" << want << "' in " << rec;
}

TEST(FwStream, ClosedPortIsUndeliveredExit4) {
  const std::string addr = closed_port();
  const stdfs::path rec = temp_path("closed.fscan");
  const CmdResult r = run(hil() + " --steps 30 --stream " + addr + " --record " + rec.string());
  EXPECT_EQ(r.code, 4) << r.out;
  const Undelivered u = undelivered_line(r.out);
  ASSERT_TRUE(u.found) << r.out;
  EXPECT_EQ(u.n, 30u);
  EXPECT_EQ(u.m, 30u);
  EXPECT_EQ(u.error, "cannot connect to " + addr + ": Connection refused") << r.out;
  EXPECT_NE(r.out.find("stripes dropped 30"), std::string::npos) << r.out;
  expect_recorded_count(rec, 30, 30);
}

TEST(FwStream, UnresolvableHostIsNamedAtStartAndAtTheEnd) {
  const CmdResult r = run(hil() + " --steps 20 --stream nosuchhost.invalid:5555");
  EXPECT_EQ(r.code, 4) << r.out;
  // Reported at start (the scan goes on: the sink keeps retrying) ...
  const std::size_t warn = r.out.find("warning: stream: cannot resolve host 'nosuchhost.invalid': ");
  EXPECT_NE(warn, std::string::npos) << r.out;
  EXPECT_LT(warn, r.out.find(": done |")) << r.out;
  // ... and in the summary.
  const Undelivered u = undelivered_line(r.out);
  ASSERT_TRUE(u.found) << r.out;
  EXPECT_EQ(u.n, 20u);
  EXPECT_EQ(u.m, 20u);
  EXPECT_EQ(u.error.rfind("cannot resolve host 'nosuchhost.invalid': ", 0), 0u) << u.error;
}

TEST(FwStream, HostThatNeverReadsLeavesStripesUndelivered) {
  Listener l(4096);
  std::atomic<bool> stop{false};
  std::thread host([&] {  // accepts, holds the connection, never reads
    int c = -1;
    while (!stop.load()) {
      pollfd p{l.fd, POLLIN, 0};
      if (c < 0 && poll(&p, 1, 20) == 1) c = accept(l.fd, nullptr, nullptr);
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    if (c >= 0) close(c);
  });
  const stdfs::path rec = temp_path("noread.fscan");
  // The host gets stream_drain_ms (300 ms here, 2 s by default) at the end to take what is queued.
  const stdfs::path cfg = temp_path("noread.json");
  std::ofstream(cfg) << R"({"stream_drain_ms": 300})";
  const CmdResult r = run(hil() + " --config " + cfg.string() + " --steps 60 --stream " + l.address() +
                          " --record " + rec.string());
  stop = true;
  host.join();
  EXPECT_EQ(r.code, 4) << r.out;
  const Undelivered u = undelivered_line(r.out);
  ASSERT_TRUE(u.found) << r.out;
  EXPECT_EQ(u.m, 60u);
  EXPECT_GT(u.n, 0u);  // the host's small receive buffer holds a few stripes at most
  EXPECT_NE(u.error.find("the host did not take the stream"), std::string::npos) << u.error;
  EXPECT_NE(u.error.find("still queued after 300 ms"), std::string::npos) << u.error;
  expect_recorded_count(rec, u.n, 60);
}

TEST(FwStream, HostThatReadsEverythingGetsEveryStripeExit0) {
  Listener l;
  std::atomic<std::uint32_t> stripes{0};
  std::thread host([&] {  // reads the stream to its end (the firmware closes the connection)
    pollfd p{l.fd, POLLIN, 0};
    if (poll(&p, 1, 20000) != 1) return;
    const int c = accept(l.fd, nullptr, nullptr);
    wire::FrameDecoder dec("host");
    std::vector<std::uint8_t> buf(1 << 16);
    for (;;) {
      const ssize_t n = recv(c, buf.data(), buf.size(), 0);
      if (n <= 0) break;
      std::span<const std::uint8_t> in(buf.data(), static_cast<std::size_t>(n));
      while (!in.empty()) {
        in = in.subspan(dec.feed(in));
        wire::FrameView f;
        while (dec.next(f))
          if (f.header.type == msg::Type::Stripe) stripes.fetch_add(1);
      }
    }
    close(c);
  });
  const CmdResult r = run(hil() + " --steps 30 --stream " + l.address());
  host.join();
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(stripes.load(), 30u);
  EXPECT_NE(r.out.find("all 30 stripes delivered"), std::string::npos) << r.out;
  EXPECT_FALSE(undelivered_line(r.out).found) << r.out;
}

// The loop's measured laser-off latency: in the summary and in the recorded Fault message. A dwell limit of
// 2 ms (shorter than the wait for a fresh camera frame) makes the loop switch the laser off between ticks.
TEST(FwStream, FaultReportsLaserOffLatency) {
  const stdfs::path cfg = temp_path("dwell.json");
  std::ofstream(cfg) << R"({"loop": {"max_dwell_ms": 2}})";
  const stdfs::path rec = temp_path("dwell.fscan");
  const CmdResult r = run(hil() + " --steps 10 --config " + cfg.string() + " --record " + rec.string());
  EXPECT_EQ(r.code, 2) << r.out;
  const std::string head = "fault 21 laser dwell limit exceeded at step 0 (state scanning): laser off after ";
  const std::size_t at = r.out.find(head);
  ASSERT_NE(at, std::string::npos) << r.out;
  const std::size_t end = r.out.find(" ms (period 0.50 ms)", at + head.size());
  ASSERT_NE(end, std::string::npos) << r.out;
  const std::string latency = r.out.substr(at + head.size(), end - at - head.size());
  const double ms = std::stod(latency);
  EXPECT_GT(ms, 0.0);
  EXPECT_LE(ms, 0.5);
  EXPECT_NE(r.out.find("laser-off latency max " + latency + " ms"), std::string::npos) << r.out;
  const Recording rr = read_recording(rec);
  bool found = false;
  for (const auto& f : rr.faults)
    if (f.code == 21) {
      found = true;
      EXPECT_NE(f.text.find("laser off after " + latency + " ms (period 0.50 ms)"), std::string::npos)
          << f.text;
    }
  EXPECT_TRUE(found);
  // A stuck laser line: the loop reads it still emitting after the off command and says so.
  const CmdResult s = run(hil() + " --steps 10 --fault laser.stuck@on=3 --record " + rec.string());
  EXPECT_EQ(s.code, 2) << s.out;
  EXPECT_NE(s.out.find("fault 20 laser monitor disagrees"), std::string::npos) << s.out;
  EXPECT_NE(s.out.find("laser line still emitting after the off command"), std::string::npos) << s.out;
  found = false;
  for (const auto& f : read_recording(rec).faults)
    found = found || (f.code == 20 && f.text.find("still emitting") != std::string::npos);
  EXPECT_TRUE(found);
}

}  // namespace
}  // namespace fs::test
