// End-to-end: `facetscan serve` as a process, fed synthetic scans over TCP: it stays responsive while a scan
// is recognized (heartbeats, SIGTERM: listener closed at once, queued scans kept as failed results with their
// .fscan, a second signal exits at once), refuses a ScanBegin beyond --memory-budget as one failed result,
// and returns memory after a large scan (RSS from /proc). Waits are on events (log lines, sockets, process
// exit), each under a generous guard; nothing asserts a duration.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/calibration.hpp"
#include "common/scan_file.hpp"
#include "common/wire.hpp"
#include "support/test_paths.hpp"

namespace {

namespace stdfs = std::filesystem;
using Clock = std::chrono::steady_clock;
constexpr auto kGuard = std::chrono::seconds(120);  // harness guard for every wait (never a measurement)

std::string read_text(const stdfs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

stdfs::path temp_dir(const std::string& name) {
  const stdfs::path d =
      stdfs::temp_directory_path() / ("facetscan-serve-" + name + "-" + std::to_string(getpid()));
  stdfs::remove_all(d);
  stdfs::create_directories(d);
  return d;
}

int free_loopback_port() {
  const int probe = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (bind(probe, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) return -1;
  socklen_t len = sizeof a;
  getsockname(probe, reinterpret_cast<sockaddr*>(&a), &len);
  close(probe);
  return ntohs(a.sin_port);
}

// One connection attempt to the port; -1 when refused.
int try_connect(int port) {
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  const int s = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (connect(s, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0) return s;
  close(s);
  return -1;
}

int connect_when_up(int port) {
  for (const auto until = Clock::now() + kGuard; Clock::now() < until;) {
    if (const int s = try_connect(port); s >= 0) return s;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return -1;
}

bool send_all(int s, const std::vector<std::uint8_t>& bytes) {
  std::size_t off = 0;
  while (off < bytes.size()) {
    const ssize_t w = send(s, bytes.data() + off, bytes.size() - off, MSG_NOSIGNAL);
    if (w <= 0) return false;
    off += static_cast<std::size_t>(w);
  }
  return true;
}

// facetscan serve as a child process, stdout and stderr into `log`.
struct Serve {
  pid_t pid = -1;
  stdfs::path log;
  int status = -1;
  bool exited = false;

  Serve(const std::vector<std::string>& extra, const stdfs::path& log_path) : log(log_path) {
    std::vector<std::string> args = {(fs::test::bin_dir() / "facetscan").string(), "serve", "-l",
                                     (fs::test::source_dir() / "hw-sim/scenes/meshes").string()};
    args.insert(args.end(), extra.begin(), extra.end());
    pid = fork();
    if (pid == 0) {
      const int fd = ::open(log.c_str(), O_CREAT | O_TRUNC | O_WRONLY, 0644);
      dup2(fd, 1);
      dup2(fd, 2);
      std::vector<char*> argv;
      for (auto& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      execv(argv[0], argv.data());
      _exit(127);
    }
  }
  ~Serve() {
    if (pid > 0 && !exited) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
    }
  }
  std::string text() const { return read_text(log); }
  bool has(const std::string& what, std::size_t count = 1) const {
    const std::string t = text();
    std::size_t n = 0;
    for (auto p = t.find(what); p != std::string::npos; p = t.find(what, p + 1)) ++n;
    return n >= count;
  }
  // Waits (event: the log) until `what` appears `count` times, or the process ends, or the guard.
  bool wait_for(const std::string& what, std::size_t count = 1) {
    for (const auto until = Clock::now() + kGuard; Clock::now() < until;) {
      if (has(what, count)) return true;
      if (!running()) return has(what, count);
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
  }
  bool running() {
    if (exited) return false;
    if (waitpid(pid, &status, WNOHANG) == pid) exited = true;
    return !exited;
  }
  // Waits for the exit (guard: then killed); the exit code, 128 + signal when killed by one.
  int wait_exit() {
    for (const auto until = Clock::now() + kGuard; Clock::now() < until && running();)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    if (!exited) return -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }
  // VmRSS / VmHWM of the process (kB).
  long status_kb(const std::string& field) const {
    std::istringstream in(read_text("/proc/" + std::to_string(pid) + "/status"));
    std::string line;
    while (std::getline(in, line))
      if (line.rfind(field + ":", 0) == 0) return std::stol(line.substr(field.size() + 1));
    return -1;
  }
};

// A synthetic scan on the wire: `steps` steps of a camera `width` x `height`, one stripe point per image row
// (a line down the middle of the image), `stripes` of them sent, ScanEnd when all are.
std::vector<std::uint8_t> scan_bytes(std::uint64_t id, std::uint32_t steps, std::uint32_t stripes,
                                     std::uint32_t width = 1280, std::uint32_t height = 1024,
                                     bool with_end = true, std::uint32_t seq = 0) {
  fs::wire::VectorSink sink;
  fs::wire::FrameWriter w(sink, seq);
  fs::msg::ScanBegin b;
  b.scan_id = id;
  b.scanner_model = "e2e synthetic";
  b.calibration = fs::ScannerCalibration::bench_default(steps);
  b.calibration.camera.width = width;
  b.calibration.camera.height = height;
  w.send(b);
  std::vector<fs::msg::StripePoint> pts(std::min<std::uint32_t>(height, 1024));  // rows 0..1023 at most
  for (std::uint32_t k = 0; k < stripes; ++k) {
    for (std::uint32_t r = 0; r < pts.size(); ++r)
      pts[r] = {static_cast<std::uint16_t>(r),
                static_cast<float>(width) * (0.2f + 0.6f * float(k) / float(steps)), 200, 3.0f};
    fs::msg::Stripe s;
    s.header.scan_id = id;
    s.header.step_index = k;
    s.header.frame_sequence = k;
    s.points = pts;
    w.send(s);
  }
  if (with_end && stripes == steps) {
    fs::msg::ScanEnd e;
    e.scan_id = id;
    e.stripes_sent = stripes;
    e.frames_captured = stripes;
    e.completed = 1;
    w.send(e);
  }
  return sink.data;
}

// The folder of the scan with this id under out/ (serve names them scan-<n>-id<id>).
stdfs::path scan_folder(const stdfs::path& out, std::uint64_t id) {
  if (stdfs::exists(out))
    for (const auto& e : stdfs::directory_iterator(out)) {
      const std::string n = e.path().filename().string();
      if (n.size() > 3 && n.substr(n.rfind("-id") + 3) == std::to_string(id)) return e.path();
    }
  return {};
}

nlohmann::json result_of(const stdfs::path& out, std::uint64_t id) {
  const stdfs::path p = scan_folder(out, id) / "result.json";
  std::ifstream f(p);
  if (!f) {
    ADD_FAILURE() << "no result.json for scan " << id << " under " << out;
    return nlohmann::json::object();
  }
  return nlohmann::json::parse(f);
}

// Stripe frames in a .fscan file (and whether it starts with the ScanBegin of `id`).
int stripes_in(const stdfs::path& fscan, std::uint64_t id) {
  fs::ScanFileReader r{fscan};
  fs::wire::DecodedMessage m;
  int stripes = 0;
  bool first = true;
  while (r.next(m)) {
    if (first && (m.type != fs::msg::Type::ScanBegin || m.scan_begin.scan_id != id)) return -1;
    first = false;
    if (m.type == fs::msg::Type::Stripe) ++stripes;
  }
  return stripes;
}

// Host heartbeats received on `s` until `want` arrived (guarded).
int read_heartbeats(int s, int want) {
  timeval tv{1, 0};
  setsockopt(s, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  fs::wire::FrameDecoder dec("from serve");
  std::vector<std::uint8_t> buf(4096);
  int hbs = 0;
  for (const auto until = Clock::now() + kGuard; hbs < want && Clock::now() < until;) {
    const ssize_t n = recv(s, buf.data(), buf.size(), 0);
    if (n == 0) break;
    if (n < 0) continue;
    std::span<const std::uint8_t> in(buf.data(), static_cast<std::size_t>(n));
    while (!in.empty()) {
      in = in.subspan(dec.feed(in));
      fs::wire::FrameView f;
      while (dec.next(f)) hbs += f.header.type == fs::msg::Type::Heartbeat ? 1 : 0;
    }
  }
  return hbs;
}

// SIGTERM while a scan is being recognized (held by the test hook): the stream side keeps sending heartbeats
// during the recognition, stops listening at once on the signal, the recognized scan is finished, the queued
// scan and the scan in progress become failed "server stopped" results whose scan.fscan holds their stripes.
TEST(ServeProcess, SigtermWhileRecognizingStopsListeningAndKeepsQueuedScans) {
  const stdfs::path dir = temp_dir("sigterm");
  const stdfs::path pause = dir / "pause";
  std::ofstream(pause) << "hold";
  const int port = free_loopback_port();
  Serve serve({"--listen", "127.0.0.1:" + std::to_string(port), "-o", (dir / "out").string(),
               "--test-pause-file", pause.string(), "--reconnect-grace", "60000"},
              dir / "serve.log");
  const int scanner = connect_when_up(port);
  ASSERT_GE(scanner, 0) << serve.text();
  ASSERT_TRUE(send_all(scanner, scan_bytes(1, 100, 100)));
  ASSERT_TRUE(serve.wait_for("processing of scan 1 paused")) << serve.text();
  ASSERT_TRUE(send_all(scanner, scan_bytes(2, 100, 100, 1280, 1024, true, 1000)));
  ASSERT_TRUE(serve.wait_for("scan 2 received, queued behind")) << serve.text();
  ASSERT_TRUE(send_all(scanner, scan_bytes(3, 100, 40, 1280, 1024, false, 2000)));  // in progress

  // Recognition is held: a new connection is accepted and gets heartbeats (the stream side is not blocked).
  const int probe = try_connect(port);
  ASSERT_GE(probe, 0);
  EXPECT_GE(read_heartbeats(probe, 3), 3) << serve.text();
  close(probe);

  ASSERT_EQ(kill(serve.pid, SIGTERM), 0);
  ASSERT_TRUE(serve.wait_for("facetscan serve: stopping")) << serve.text();
  // The listener is closed at once (the poll loop did not wait for the recognition)...
  bool refused = false;
  for (const auto until = Clock::now() + kGuard; !refused && Clock::now() < until;) {
    const int s = try_connect(port);
    refused = s < 0;
    if (s >= 0) close(s);
  }
  EXPECT_TRUE(refused);
  // ... and the scan being recognized is finished: serve is still there while it is held.
  EXPECT_TRUE(serve.running());
  stdfs::remove(pause);
  EXPECT_EQ(serve.wait_exit(), 0) << serve.text();
  close(scanner);

  const std::string log = serve.text();
  const stdfs::path out = dir / "out";
  const nlohmann::json r1 = result_of(out, 1);
  EXPECT_FALSE(r1.contains("failed")) << r1.dump(1);
  EXPECT_EQ(r1["scan"]["status"], "complete");
  const nlohmann::json r2 = result_of(out, 2);
  EXPECT_TRUE(r2.value("failed", false)) << r2.dump(1);
  EXPECT_NE(r2.value("error", "").find("server stopped"), std::string::npos) << r2.dump(1);
  EXPECT_EQ(r2["scan"]["status"], "complete");
  EXPECT_EQ(stripes_in(scan_folder(out, 2) / "scan.fscan", 2), 100);
  const nlohmann::json r3 = result_of(out, 3);
  EXPECT_TRUE(r3.value("failed", false)) << r3.dump(1);
  EXPECT_EQ(r3["scan"]["status"], "disconnected before ScanEnd");
  EXPECT_EQ(stripes_in(scan_folder(out, 3) / "scan.fscan", 3), r3["scan"]["stripes"].get<int>());
  EXPECT_NE(log.find("3 scan(s), 2 connection(s)"), std::string::npos) << log;
  EXPECT_NE(log.find(", 2 failed, 2 not processed (server stopped)"), std::string::npos) << log;
}

// A second SIGTERM while the first one waits for the recognition exits at once.
TEST(ServeProcess, ASecondSignalExitsAtOnce) {
  const stdfs::path dir = temp_dir("sigterm2");
  const stdfs::path pause = dir / "pause";
  std::ofstream(pause) << "hold";
  const int port = free_loopback_port();
  Serve serve({"--listen", "127.0.0.1:" + std::to_string(port), "--test-pause-file", pause.string()},
              dir / "serve.log");
  const int scanner = connect_when_up(port);
  ASSERT_GE(scanner, 0) << serve.text();
  ASSERT_TRUE(send_all(scanner, scan_bytes(1, 50, 50)));
  ASSERT_TRUE(serve.wait_for("processing of scan 1 paused")) << serve.text();
  ASSERT_EQ(kill(serve.pid, SIGTERM), 0);
  ASSERT_TRUE(serve.wait_for("facetscan serve: stopping")) << serve.text();
  EXPECT_TRUE(serve.running());  // waiting for the held recognition
  ASSERT_EQ(kill(serve.pid, SIGTERM), 0);
  EXPECT_EQ(serve.wait_exit(), 128 + SIGTERM) << serve.text();
  close(scanner);
}

// A ScanBegin beyond --memory-budget is one failed result (logged with the reason, result.json, scan.fscan
// holding the ScanBegin), the connection and the server go on with the next scan.
TEST(ServeProcess, AScanBeyondTheMemoryBudgetIsAFailedResult) {
  const stdfs::path dir = temp_dir("budget");
  const int port = free_loopback_port();
  Serve serve({"--listen", "127.0.0.1:" + std::to_string(port), "-o", (dir / "out").string(),
               "--memory-budget", "256M", "--max-scans", "2"},
              dir / "serve.log");
  const int scanner = connect_when_up(port);
  ASSERT_GE(scanner, 0) << serve.text();
  ASSERT_TRUE(serve.wait_for("memory budget 256 MiB")) << serve.text();  // the listening line
  auto bytes = scan_bytes(1, 20, 20, 16384, 16384);                      // a 268 M-entry ray table
  const auto good = scan_bytes(2, 100, 100, 1280, 1024, true, 1000);
  bytes.insert(bytes.end(), good.begin(), good.end());
  ASSERT_TRUE(send_all(scanner, bytes));
  EXPECT_EQ(serve.wait_exit(), 0) << serve.text();
  close(scanner);
  const std::string log = serve.text();
  EXPECT_NE(log.find("scan 1 from 127.0.0.1:"), std::string::npos) << log;
  EXPECT_NE(log.find("(REFUSED at ScanBegin): FAILED: ScanBegin of scan 1: camera 16384 x 16384"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("2 scan(s), 1 connection(s), 0 disconnect(s), 1 failed, 1 ScanBegin(s) refused"),
            std::string::npos)
      << log;
  const nlohmann::json r1 = result_of(dir / "out", 1);
  EXPECT_TRUE(r1.value("failed", false)) << r1.dump(1);
  EXPECT_NE(r1.value("error", "").find("memory budget of 256 MiB"), std::string::npos) << r1.dump(1);
  EXPECT_EQ(r1["scan"]["status"], "refused at ScanBegin");
  EXPECT_EQ(stripes_in(scan_folder(dir / "out", 1) / "scan.fscan", 1), 0);
  const nlohmann::json r2 = result_of(dir / "out", 2);
  EXPECT_FALSE(r2.contains("failed")) << r2.dump(1);
}

// After a scan much larger than the working size, serve returns the memory: RSS after big + normal scans is
// near the RSS after the normal scan alone, while the peak shows the big scan really used memory.
TEST(ServeProcess, MemoryIsReturnedAfterALargeScan) {
  const stdfs::path dir = temp_dir("rss");
  const int port = free_loopback_port();
#if defined(__SANITIZE_ADDRESS__)
  // Under ASan (the CI build) freed memory waits in ASan's quarantine and its allocator, not glibc's, which
  // malloc_trim cannot reach: let serve's ASan release freed memory at once, so RSS measures serve's own
  // frees.
  const char* asan = std::getenv("ASAN_OPTIONS");
  const std::string options = std::string(asan ? asan : "") + (asan && *asan ? ":" : "") +
                              "quarantine_size_mb=0:allocator_release_to_os_interval_ms=0";
  setenv("ASAN_OPTIONS", options.c_str(), 1);
#endif
  Serve serve({"--listen", "127.0.0.1:" + std::to_string(port)}, dir / "serve.log");
  // One connection per scan: this client sends no heartbeats, so serve closes a connection that stays silent
  // for its link timeout (a long recognition of the large scan on a loaded machine).
  std::vector<int> links;
  const auto send_scan = [&](const std::vector<std::uint8_t>& bytes) {
    links.push_back(connect_when_up(port));
    return links.back() >= 0 && send_all(links.back(), bytes);
  };
  ASSERT_TRUE(send_scan(scan_bytes(1, 300, 300))) << serve.text();
  ASSERT_TRUE(serve.wait_for("object(s)", 1)) << serve.text();
  ASSERT_TRUE(send_scan(scan_bytes(2, 300, 300)));
  ASSERT_TRUE(serve.wait_for("object(s)", 2)) << serve.text();
  const long normal = serve.status_kb("VmRSS");
  ASSERT_GT(normal, 0);
  ASSERT_TRUE(send_scan(scan_bytes(3, 4000, 4000)));  // 4 M cells: 8 x the working size
  ASSERT_TRUE(serve.wait_for("object(s)", 3)) << serve.text();
  ASSERT_TRUE(send_scan(scan_bytes(4, 300, 300)));
  ASSERT_TRUE(serve.wait_for("object(s)", 4)) << serve.text();
  const long after = serve.status_kb("VmRSS");
  const long peak = serve.status_kb("VmHWM");
  std::printf("METRIC serve_rss_kb normal=%ld peak=%ld after_large=%ld\n", normal, peak, after);
  EXPECT_GT(peak, 2 * normal) << "the large scan did not use much memory: the test tests nothing";
  EXPECT_LT(after, normal + normal / 4)
      << "normal " << normal << " kB, after the large scan " << after << " kB";
  kill(serve.pid, SIGTERM);
  EXPECT_EQ(serve.wait_exit(), 0) << serve.text();
  for (int s : links) close(s);
}

}  // namespace
