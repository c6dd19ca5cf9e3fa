// The `facetscan serve` attack suite (issue #25): a real serve process (this build's binary) and raw TCP
// clients that speak the wire protocol with the project's own encoder (common/wire.hpp). Every test starts
// its own serve, runs one attack, and then checks what the issue demands of serve after any attack:
//  * the process is alive and a fresh connection receives host Heartbeat frames (decoded with FrameDecoder)
//    within a generous number of heartbeat periods;
//  * its peak RSS (/proc/PID/status VmHWM) stayed under the memory budget (--memory-budget 512M);
//  * a valid scan sent afterwards (the hw-sim pyramid, recorded once by facetscan-fw-hil) is recognized;
//  * SIGTERM ends it with exit code 0 and a summary that counts the failed scans and protocol errors caused.
// A watchdog kills serve (SIGKILL) if its RSS passes a hard cap far above the budget, so that an attack that
// makes serve allocate gigabytes fails the test instead of exhausting the machine.
//
// FACETSCAN_ATTACK_ROUNDS=N (default 200) sets the connections of the random-sequence test,
// FACETSCAN_ATTACK_SEED=S its seed (default 25); FACETSCAN_ATTACK_FACETSCAN=PATH attacks another build's
// facetscan binary (default: this build's); FACETSCAN_ATTACK_KEEP=1 keeps serve's log and results of passing
// tests too.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/file.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <memory>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/calibration.hpp"
#include "common/crc32c.hpp"
#include "common/scan_file.hpp"
#include "common/wire.hpp"
#include "support/test_paths.hpp"

extern char** environ;

namespace {

namespace stdfs = std::filesystem;
namespace msg = fs::msg;
namespace wire = fs::wire;
using Bytes = std::vector<std::uint8_t>;
using SteadyClock = std::chrono::steady_clock;
using std::chrono::milliseconds;
using std::chrono::seconds;

// ------------------------------------------------------------------------------------------- settings

constexpr std::uint64_t kBudgetBytes = std::uint64_t{512} << 20;  // --memory-budget 512M
constexpr const char* kBudgetArg = "512M";
constexpr int kHeartbeatPeriodMs = 500;  // the host's heartbeat period (host-pipeline.md, "live stream")
constexpr int kReconnectGraceMs = 300;   // serve --reconnect-grace in these tests
// Hang guards: how long to wait for an event before giving up. Never asserted as deadlines.
constexpr auto kEventGuard = seconds(60);
constexpr int kHeartbeatGuardPeriods = 20;  // "a generous number of heartbeat periods"

#if defined(__SANITIZE_ADDRESS__)
constexpr bool kAsan = true;
#else
constexpr bool kAsan = false;
#endif

// The RSS serve must stay under. Under AddressSanitizer the process also holds the shadow memory (1/8 of
// what the program touches), the quarantine of freed blocks (capped at 64 MB by the ASAN_OPTIONS serve gets
// here) and the allocator's per-size-class caches; those are the sanitizer's, not serve's, so the limit
// allows for them.
std::uint64_t rss_limit_bytes() { return kAsan ? kBudgetBytes + kBudgetBytes / 2 : kBudgetBytes; }
// The watchdog's hard cap: far above the budget, far below what hurts the machine.
std::uint64_t rss_kill_bytes() { return std::uint64_t{2} << 30; }

int env_int(const char* name, int fallback) {
  const char* v = std::getenv(name);
  if (!v || !*v) return fallback;
  return std::atoi(v);
}

// The facetscan binary under attack.
std::string facetscan_binary() {
  const char* v = std::getenv("FACETSCAN_ATTACK_FACETSCAN");
  return v && *v ? std::string(v) : (fs::test::bin_dir() / "facetscan").string();
}

// ------------------------------------------------------------------------------------------- files

std::string read_text(const stdfs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

// The log's lines that contain `what`.
std::vector<std::string> lines_with(const std::string& text, const std::string& what) {
  std::vector<std::string> v;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (line.find(what) != std::string::npos) v.push_back(line);
  return v;
}

std::string tail(const std::string& text, std::size_t n = 6000) {
  return text.size() <= n ? text : "...\n" + text.substr(text.size() - n);
}

// ------------------------------------------------------------------------------------------- scans

struct OwnedStripe {
  msg::StripeHeader header;
  std::vector<msg::StripePoint> points;
};
struct OwnedScan {
  msg::ScanBegin begin;
  std::vector<OwnedStripe> stripes;
  msg::ScanEnd end;
};

// Frames with consecutive sequence numbers, encoded by the project's encoder.
class Stream {
 public:
  explicit Stream(std::uint32_t first_sequence = 0) : seq_(first_sequence) {}
  template <class M>
  Stream& add(const M& m) {
    const std::size_t at = bytes.size();
    bytes.resize(at + wire::frame_size(m));
    wire::encode(std::span(bytes).subspan(at), seq_++, m);
    return *this;
  }
  Stream& stripe(const msg::StripeHeader& h, std::vector<msg::StripePoint> points) {
    return add(msg::Stripe{h, std::span<msg::StripePoint>(points)});
  }
  Stream& stripe(const OwnedStripe& s) { return stripe(s.header, s.points); }
  Stream& heartbeat() {
    msg::Heartbeat hb;
    hb.counter = seq_;
    return add(hb);
  }
  Stream& raw(const Bytes& b) {
    bytes.insert(bytes.end(), b.begin(), b.end());
    ++seq_;
    return *this;
  }
  std::uint32_t sequence() const { return seq_; }
  Bytes bytes;

 private:
  std::uint32_t seq_;
};

// One encoded frame.
template <class M>
Bytes frame_of(const M& m, std::uint32_t seq = 0) {
  Bytes b(wire::frame_size(m));
  wire::encode(b, seq, m);
  return b;
}

// Rewrites a frame's CRC after its bytes were changed (so that the change reaches the payload decoder).
void fix_crc(Bytes& frame) {
  const std::size_t n = frame.size() - wire::kFrameCrcSize;
  const std::uint32_t crc = fs::crc32c(std::span<const std::uint8_t>(frame.data(), n));
  for (int i = 0; i < 4; ++i)
    frame[n + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(crc >> (8 * i));
}
void put_u32(Bytes& b, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v >> (8 * i));
}

// The scan with every message carrying `id` (begin / stripes [from, to) / end as asked).
Bytes scan_bytes(const OwnedScan& s, std::uint64_t id, bool begin = true, std::size_t from = 0,
                 std::size_t to = std::numeric_limits<std::size_t>::max(), bool end = true,
                 std::uint32_t first_sequence = 0) {
  Stream st(first_sequence);
  if (begin) {
    msg::ScanBegin b = s.begin;
    b.scan_id = id;
    st.add(b);
  }
  to = std::min(to, s.stripes.size());
  for (std::size_t i = from; i < to; ++i) {
    msg::StripeHeader h = s.stripes[i].header;
    h.scan_id = id;
    st.stripe(h, s.stripes[i].points);
  }
  if (end) {
    msg::ScanEnd e = s.end;
    e.scan_id = id;
    st.add(e);
  }
  return std::move(st.bytes);
}

OwnedScan read_owned_scan(const stdfs::path& file) {
  OwnedScan s;
  fs::ScanFileReader r(file);
  wire::DecodedMessage m;
  bool begun = false, ended = false;
  while (!ended && r.next(m)) {
    switch (m.type) {
      case msg::Type::ScanBegin:
        s.begin = m.scan_begin;
        begun = true;
        break;
      case msg::Type::Stripe:
        if (begun) s.stripes.push_back({m.stripe.header, {m.stripe.points.begin(), m.stripe.points.end()}});
        break;
      case msg::Type::ScanEnd:
        s.end = m.scan_end;
        ended = begun;
        break;
      default:
        break;
    }
  }
  if (!ended) throw fs::Error(file.string() + ": no whole scan in the recording");
  return s;
}

// The valid scan: hw-sim's pyramid scene (hw-sim/scenes/pyramid.json) scanned by facetscan-fw-hil on the
// simulated devices and recorded. Recorded once per build (again when facetscan-fw-hil is newer), under a
// file lock: ctest runs each test in its own process, possibly in parallel.
const OwnedScan& pyramid_scan() {
  static const OwnedScan scan = [] {
    const stdfs::path dir = fs::test::bin_dir().parent_path() / "serve-attack-work";
    stdfs::create_directories(dir);
    const stdfs::path fw = fs::test::bin_dir() / "facetscan-fw-hil";
    const stdfs::path rec = dir / "pyramid.fscan";
    const int lock = ::open((dir / "pyramid.lock").c_str(), O_CREAT | O_RDWR | O_CLOEXEC, 0644);
    if (lock >= 0) ::flock(lock, LOCK_EX);
    if (!stdfs::exists(rec) || stdfs::last_write_time(rec) < stdfs::last_write_time(fw)) {
      const stdfs::path tmp = dir / ("pyramid.fscan.tmp" + std::to_string(::getpid()));
      const std::string cmd = fw.string() + " --galvo sim --camera sim --scene " +
                              (fs::test::source_dir() / "hw-sim/scenes/pyramid.json").string() +
                              " --record " + tmp.string() + " > " + (dir / "record.log").string() + " 2>&1";
      const int rc = std::system(cmd.c_str());
      if (rc != 0) {
        if (lock >= 0) ::close(lock);
        throw fs::Error("recording the valid scan failed (" + cmd + "):\n" + read_text(dir / "record.log"));
      }
      stdfs::rename(tmp, rec);
    }
    if (lock >= 0) ::close(lock);
    return read_owned_scan(rec);
  }();
  return scan;
}

// A small scan of the bench calibration with a steps x rows (x cols) camera and one point per row.
OwnedScan synthetic_scan(std::uint32_t steps, std::uint32_t rows, std::uint32_t cols = 1280) {
  OwnedScan s;
  s.begin.scanner_model = "attack";
  s.begin.calibration = fs::ScannerCalibration::bench_default(steps);
  s.begin.calibration.camera.width = cols;
  s.begin.calibration.camera.height = rows;
  const std::uint32_t n = std::min<std::uint32_t>(rows, 64);
  for (std::uint32_t k = 0; k < std::min<std::uint32_t>(steps, 8); ++k) {
    OwnedStripe st;
    st.header.step_index = k;
    st.header.frame_sequence = k;
    for (std::uint32_t r = 0; r < n; ++r)
      st.points.push_back({static_cast<std::uint16_t>(r), 10.0f + float(k), 200, 2.0f});
    s.stripes.push_back(std::move(st));
  }
  s.end.stripes_sent = static_cast<std::uint32_t>(s.stripes.size());
  s.end.completed = 1;
  return s;
}

// ------------------------------------------------------------------------------------------- results

struct Result {
  stdfs::path path;
  nlohmann::json j;
  std::uint64_t scan_id() const { return j.at("scan").at("scan_id").get<std::uint64_t>(); }
  bool failed() const { return j.contains("failed") && j["failed"].get<bool>(); }
  std::string status() const { return j.at("scan").at("status").get<std::string>(); }
};

// Every result.json under dir that parses (one being written is skipped until it is whole).
std::vector<Result> read_results(const stdfs::path& dir, bool strict = false) {
  std::vector<Result> v;
  if (!stdfs::exists(dir)) return v;
  std::vector<stdfs::path> paths;
  for (const auto& e : stdfs::recursive_directory_iterator(dir))
    if (e.path().filename() == "result.json") paths.push_back(e.path());
  std::sort(paths.begin(), paths.end());
  for (const auto& p : paths) {
    const std::string text = read_text(p);
    try {
      Result r{p, nlohmann::json::parse(text)};
      r.scan_id();  // has a scan object
      v.push_back(std::move(r));
    } catch (const std::exception& e) {
      if (strict) ADD_FAILURE() << p << " is not a result: " << e.what() << "\n" << text;
    }
  }
  return v;
}

std::vector<Result> results_for(const stdfs::path& dir, std::uint64_t id) {
  std::vector<Result> v;
  for (auto& r : read_results(dir))
    if (r.scan_id() == id) v.push_back(std::move(r));
  return v;
}

// The number right before the first `what` in `line` (0 when there is none). (No std::regex: GCC 12 warns
// inside it at -O1.)
long number_before(const std::string& line, const std::string& what) {
  for (auto at = line.find(what); at != std::string::npos; at = line.find(what, at + 1)) {
    std::size_t from = at;
    while (from > 0 && std::isdigit(static_cast<unsigned char>(line[from - 1]))) --from;
    if (from < at) return std::stol(line.substr(from, at - from));
  }
  return 0;
}

// The summary serve prints when it stops:
// "facetscan serve: N scan(s), C connection(s), D disconnect(s)[, F failed][, P protocol error(s) ...]".
struct Summary {
  bool found = false;
  std::string line;
  long scans = 0, connections = 0, failed = 0, protocol_errors = 0;
};
Summary parse_summary(const std::string& log) {
  Summary s;
  const auto lines = lines_with(log, " scan(s), ");
  for (const auto& l : lines)
    if (l.rfind("facetscan serve: ", 0) == 0) s.line = l;
  if (s.line.empty()) return s;
  s.found = true;
  s.scans = number_before(s.line, " scan(s)");
  s.connections = number_before(s.line, " connection(s)");
  s.failed = number_before(s.line, " failed");
  s.protocol_errors = number_before(s.line, " protocol error(s)");
  return s;
}

// ------------------------------------------------------------------------------------------- clients

int connect_loopback(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  if (fd < 0 || ::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    if (fd >= 0) ::close(fd);
    return -1;
  }
  return fd;
}

// Host Heartbeat frames in what the host sent; throws (a test failure) on a malformed frame.
int heartbeats_in(const Bytes& received) {
  wire::FrameDecoder dec("from serve");
  wire::FrameView f;
  msg::Heartbeat hb;
  int n = 0;
  for (std::span<const std::uint8_t> in(received); !in.empty();) {
    in = in.subspan(dec.feed(in));
    while (dec.next(f)) {
      if (f.header.type != msg::Type::Heartbeat) continue;
      wire::decode(f, hb, dec.source());
      ++n;
    }
  }
  return n;
}

// A scanner's connection: raw bytes out, whatever the host sends collected.
class Client {
 public:
  explicit Client(int port) : fd_(connect_loopback(port)) {}
  ~Client() {
    if (fd_ >= 0) ::close(fd_);
  }
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;
  bool ok() const { return fd_ >= 0; }
  int local_port() const {
    sockaddr_in a{};
    socklen_t len = sizeof a;
    if (fd_ < 0 || ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len) != 0) return -1;
    return ntohs(a.sin_port);
  }
  // All bytes, in chunks of at most `chunk`; false once the host closed the connection.
  bool send(std::span<const std::uint8_t> bytes, std::size_t chunk = std::size_t{1} << 20) {
    while (fd_ >= 0 && !bytes.empty()) {
      const ssize_t w = ::send(fd_, bytes.data(), std::min(chunk, bytes.size()), MSG_NOSIGNAL);
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) return false;
      bytes = bytes.subspan(static_cast<std::size_t>(w));
      pump();
    }
    return fd_ >= 0;
  }
  // Takes what the host sent so far, without waiting; false once the host closed the connection.
  bool pump(int wait_ms = 0) {
    if (fd_ < 0 || closed_) return false;
    pollfd p{fd_, POLLIN, 0};
    while (::poll(&p, 1, wait_ms) > 0) {
      std::uint8_t buf[4096];
      const ssize_t r = ::recv(fd_, buf, sizeof buf, MSG_DONTWAIT);
      if (r > 0) {
        received_.insert(received_.end(), buf, buf + r);
        wait_ms = 0;
        continue;
      }
      if (r < 0 && (errno == EAGAIN || errno == EINTR)) break;
      closed_ = true;  // EOF or reset
      break;
    }
    return !closed_;
  }
  // Ends the stream (FIN) and reads until the host closes its side, so that the host has read every byte
  // before this returns. False when the host kept the connection open for the whole guard.
  bool finish() {
    if (fd_ < 0) return false;
    ::shutdown(fd_, SHUT_WR);
    const auto until = SteadyClock::now() + kEventGuard;
    while (!closed_ && SteadyClock::now() < until) pump(100);
    return closed_;
  }
  // Resets the connection (RST, no FIN).
  void abort() {
    if (fd_ < 0) return;
    const linger l{1, 0};
    ::setsockopt(fd_, SOL_SOCKET, SO_LINGER, &l, sizeof l);
    ::close(fd_);
    fd_ = -1;
  }
  bool host_closed() const { return closed_; }
  const Bytes& received() const { return received_; }

 private:
  int fd_;
  bool closed_ = false;
  Bytes received_;
};

// ------------------------------------------------------------------------------------------- serve

bool serve_has_memory_budget() {
  static const bool has = [] {
    const std::string cmd = facetscan_binary() + " serve --help 2>&1";
    FILE* p = ::popen(cmd.c_str(), "r");
    if (!p) return false;
    std::string out;
    char buf[4096];
    for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, p)) > 0;) out.append(buf, n);
    ::pclose(p);
    return out.find("--memory-budget") != std::string::npos;
  }();
  return has;
}

// A `facetscan serve --listen 127.0.0.1:0` process with its output in a log file, and a watchdog that
// records its peak RSS and kills it past rss_kill_bytes().
class ServeProcess {
 public:
  explicit ServeProcess(const std::string& name) {
    dir_ = stdfs::temp_directory_path() / ("facetscan-attack-" + name + "-" + std::to_string(::getpid()));
    stdfs::remove_all(dir_);
    stdfs::create_directories(dir_);
    out_ = dir_ / "scans";
    log_ = dir_ / "serve.log";
    std::vector<std::string> args = {facetscan_binary(),
                                     "serve",
                                     "--listen",
                                     "127.0.0.1:0",
                                     "-l",
                                     (fs::test::source_dir() / "hw-sim/scenes/meshes").string(),
                                     "-o",
                                     out_.string(),
                                     "--reconnect-grace",
                                     std::to_string(kReconnectGraceMs)};
    if (serve_has_memory_budget()) args.insert(args.end(), {"--memory-budget", kBudgetArg});
    // Under ASan: a small quarantine, so that freed memory does not count as serve's (see rss_limit_bytes).
    std::vector<std::string> env;
    bool have_asan_options = false;
    for (char** e = environ; *e; ++e) {
      std::string v = *e;
      if (v.rfind("ASAN_OPTIONS=", 0) == 0) {
        v += ":quarantine_size_mb=64";
        have_asan_options = true;
      }
      env.push_back(v);
    }
    if (!have_asan_options) env.push_back("ASAN_OPTIONS=quarantine_size_mb=64");
    std::vector<char*> argv, envp;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    for (auto& e : env) envp.push_back(e.data());
    envp.push_back(nullptr);
    // fork + exec rather than posix_spawn: the child asks to be killed when this process dies (a ctest
    // timeout), so that no serve outlives its test.
    const int log_fd = ::open(log_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    const pid_t parent = ::getpid();
    pid_ = log_fd < 0 ? -1 : ::fork();
    if (pid_ == 0) {
      ::prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (::getppid() != parent) ::_exit(127);
      ::dup2(log_fd, 1);
      ::dup2(log_fd, 2);
      ::execve(argv[0], argv.data(), envp.data());
      ::_exit(127);
    }
    if (log_fd >= 0) ::close(log_fd);
    const int rc = pid_ > 0 ? 0 : -1;
    command_ = args[0];
    for (std::size_t i = 1; i < args.size(); ++i) command_ += " " + args[i];
    if (rc != 0) {
      pid_ = -1;
      return;
    }
    watchdog_ = std::thread([this] { watch(); });
    // The listening line names the port.
    const auto until = SteadyClock::now() + kEventGuard;
    while (alive() && SteadyClock::now() < until) {
      const std::string text = log();
      const auto at = text.find("listening on ");
      const auto p = at == std::string::npos ? at : text.find("(port ", at);
      if (p != std::string::npos && std::isdigit(static_cast<unsigned char>(text[p + 6]))) {
        port_ = std::stoi(text.substr(p + 6));
        break;
      }
      std::this_thread::sleep_for(milliseconds(20));
    }
  }
  ~ServeProcess() {
    if (pid_ > 0 && !reaped_) {
      ::kill(pid_, SIGKILL);
      reap(true);
    }
  }
  ServeProcess(const ServeProcess&) = delete;
  ServeProcess& operator=(const ServeProcess&) = delete;

  bool started() const { return pid_ > 0 && port_ > 0; }
  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  const stdfs::path& dir() const { return dir_; }
  const stdfs::path& out() const { return out_; }
  const std::string& command() const { return command_; }
  std::string log() const { return read_text(log_); }

  // Running (not exited, not reaped); does not reap, so that the pid stays ours.
  bool alive() const {
    if (pid_ <= 0 || reaped_) return false;
    siginfo_t info{};
    if (::waitid(P_PID, static_cast<id_t>(pid_), &info, WEXITED | WNOHANG | WNOWAIT) != 0) return false;
    return info.si_pid == 0;
  }
  // "VmRSS" / "VmHWM" of /proc/PID/status in bytes (0 when gone).
  std::uint64_t vm_bytes(const char* field) const {
    std::ifstream f("/proc/" + std::to_string(pid_) + "/status");
    for (std::string line; std::getline(f, line);)
      if (line.rfind(std::string(field) + ":", 0) == 0)
        return std::stoull(line.substr(line.find(':') + 1)) * 1024;
    return 0;
  }
  std::uint64_t peak_rss() const {
    return std::max<std::uint64_t>(peak_rss_, alive() ? vm_bytes("VmHWM") : 0);
  }
  bool killed_by_watchdog() const { return watchdog_killed_; }

  // Kills it now (the watchdog's reason or a test's) and reaps it.
  void kill_now() {
    if (pid_ > 0 && !reaped_) {
      ::kill(pid_, SIGKILL);
      reap(true);
    }
  }
  // SIGTERM, then waits (hang guard; SIGKILL after it). The exit code, or -1 (killed / signalled).
  int terminate() {
    if (pid_ <= 0 || reaped_) return exit_code_;
    ::kill(pid_, SIGTERM);
    const auto until = SteadyClock::now() + kEventGuard;
    while (alive() && SteadyClock::now() < until) std::this_thread::sleep_for(milliseconds(20));
    reap(alive());
    return exit_code_;
  }
  std::string how_it_ended() const { return ended_; }

 private:
  void watch() {
    while (!stop_watch_) {
      if (!alive()) break;
      const std::uint64_t rss = vm_bytes("VmRSS");
      peak_rss_ = std::max<std::uint64_t>(peak_rss_, std::max(rss, vm_bytes("VmHWM")));
      if (rss > rss_kill_bytes()) {
        watchdog_killed_ = true;
        ::kill(pid_, SIGKILL);
        break;
      }
      std::this_thread::sleep_for(milliseconds(5));
    }
  }
  void reap(bool kill_first) {
    if (kill_first) ::kill(pid_, SIGKILL);
    stop_watch_ = true;
    if (watchdog_.joinable()) watchdog_.join();
    int status = 0;
    ::waitpid(pid_, &status, 0);
    reaped_ = true;
    if (WIFEXITED(status)) {
      exit_code_ = WEXITSTATUS(status);
      ended_ = "exit code " + std::to_string(exit_code_);
    } else if (WIFSIGNALED(status)) {
      ended_ = std::string("killed by signal ") + strsignal(WTERMSIG(status));
    }
  }

  stdfs::path dir_, out_, log_;
  std::string command_;
  pid_t pid_ = -1;
  int port_ = 0;
  bool reaped_ = false;
  int exit_code_ = -1;
  std::string ended_ = "running";
  std::thread watchdog_;
  std::atomic<bool> stop_watch_{false};
  std::atomic<bool> watchdog_killed_{false};
  std::atomic<std::uint64_t> peak_rss_{0};
};

std::string mb(std::uint64_t bytes) { return std::to_string(bytes >> 20) + " MB"; }

// Waits (hang guard) until pred() or serve is gone.
template <class Pred>
bool wait_until(const ServeProcess& s, Pred pred, std::chrono::milliseconds guard = kEventGuard) {
  const auto until = SteadyClock::now() + guard;
  for (;;) {
    if (pred()) return true;
    if (!s.alive() || SteadyClock::now() >= until) return pred();
    std::this_thread::sleep_for(milliseconds(20));
  }
}

// The host Heartbeats a fresh connection receives: at least `want` (the greeting and a periodic one)
// within kHeartbeatGuardPeriods periods.
int probe_heartbeats(int port, int want = 2) {
  Client c(port);
  if (!c.ok()) return -1;
  const auto until = SteadyClock::now() + milliseconds(kHeartbeatPeriodMs * kHeartbeatGuardPeriods);
  int n = 0;
  while (SteadyClock::now() < until && c.pump(50)) {
    n = heartbeats_in(c.received());
    if (n >= want) break;
  }
  return heartbeats_in(c.received());
}

// ------------------------------------------------------------------------------------------- fixture

class ServeAttack : public ::testing::Test {
 public:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    ASSERT_NO_THROW(pyramid_scan());  // recorded before serve starts (fw-hil takes a few seconds)
    if (!serve_has_memory_budget())
      std::printf(
          "[ NOTE     ] this serve has no --memory-budget option: it runs without one; the RSS limit "
          "(%s) is checked all the same\n",
          mb(rss_limit_bytes()).c_str());
    serve_ = std::make_unique<ServeProcess>(info->name());
    ASSERT_TRUE(serve_->started()) << serve_->command() << "\n" << serve_->log();
  }
  void TearDown() override {
    const bool keep = HasFailure() || env_int("FACETSCAN_ATTACK_KEEP", 0) != 0;
    const stdfs::path dir = serve_ ? serve_->dir() : stdfs::path();
    serve_.reset();
    if (keep)
      std::printf("[ KEPT     ] serve's log and results: %s\n", dir.c_str());
    else if (!dir.empty())
      stdfs::remove_all(dir);
  }

  ServeProcess& serve() { return *serve_; }
  const stdfs::path& out() { return serve_->out(); }

  // What must hold after any attack: serve alive, heartbeats to a fresh connection, peak RSS under the limit.
  ::testing::AssertionResult healthy(const std::string& after) {
    if (serve_->killed_by_watchdog())
      return ::testing::AssertionFailure()
             << "after " << after << ": serve passed " << mb(rss_kill_bytes())
             << " of RSS and was killed by the test's watchdog (budget " << mb(kBudgetBytes) << ")\n"
             << tail(serve_->log());
    if (!serve_->alive()) {
      serve_->kill_now();  // reaps it
      return ::testing::AssertionFailure()
             << "after " << after << ": serve is gone (" << serve_->how_it_ended() << ")\n"
             << tail(serve_->log());
    }
    const int hb = probe_heartbeats(serve_->port());
    if (hb < 2)
      return ::testing::AssertionFailure()
             << "after " << after << ": a fresh connection got " << hb << " host heartbeat(s) in "
             << kHeartbeatGuardPeriods << " heartbeat periods (want 2)\n"
             << tail(serve_->log());
    const std::uint64_t peak = serve_->peak_rss();
    if (peak >= rss_limit_bytes())
      return ::testing::AssertionFailure() << "after " << after << ": serve's peak RSS " << mb(peak)
                                           << " is not under " << mb(rss_limit_bytes()) << " (budget "
                                           << mb(kBudgetBytes) << (kAsan ? " + ASan's share)" : ")");
    return ::testing::AssertionSuccess();
  }

  // Sends `bytes` on a new connection and ends it cleanly (the host has read everything when this returns).
  // The local port of the connection, or -1.
  int send_scan(const Bytes& bytes, bool require_all_sent = true) {
    Client c(serve_->port());
    if (!c.ok()) {
      ADD_FAILURE() << "cannot connect to serve";
      return -1;
    }
    const int port = c.local_port();
    const bool sent = c.send(bytes);
    if (require_all_sent) {
      EXPECT_TRUE(sent) << "serve closed the connection\n" << tail(serve_->log());
    }
    EXPECT_TRUE(c.finish()) << "serve did not close a finished connection\n" << tail(serve_->log());
    return port;
  }

  // Waits for the one result of scan `id`.
  std::vector<Result> wait_results(std::uint64_t id, std::size_t n = 1) {
    wait_until(*serve_, [&] { return results_for(out(), id).size() >= n; });
    return results_for(out(), id);
  }

  // The end of every attack: serve is healthy, recognizes a valid scan (the pyramid, as scan `id`), and
  // SIGTERM ends it with exit code 0 and its summary.
  Summary finish(std::uint64_t id = 999'000'001) {
    Summary s;
    EXPECT_TRUE(healthy("the attack"));
    if (!serve_->alive()) return s;
    send_scan(scan_bytes(pyramid_scan(), id));
    const auto r = wait_results(id);
    EXPECT_EQ(r.size(), 1u) << "the valid scan sent after the attack has no result\n" << tail(serve_->log());
    if (r.size() == 1) {
      EXPECT_FALSE(r[0].failed()) << r[0].j.dump(1);
      EXPECT_EQ(r[0].status(), "complete") << r[0].j.dump(1);
      bool pyramid = false;
      if (r[0].j.contains("objects"))
        for (const auto& o : r[0].j["objects"])
          pyramid = pyramid || o.value("model", "") == "truncated_pyramid";
      EXPECT_TRUE(pyramid) << "the valid scan after the attack is not recognized: " << r[0].j.dump(1);
    }
    EXPECT_TRUE(healthy("the valid scan"));
    std::printf("[ RSS      ] serve's peak RSS %s (limit %s)\n", mb(serve_->peak_rss()).c_str(),
                mb(rss_limit_bytes()).c_str());
    const int code = serve_->terminate();
    const std::string log = serve_->log();
    EXPECT_EQ(code, 0) << "SIGTERM: serve ended with " << serve_->how_it_ended() << "\n" << tail(log);
    s = parse_summary(log);
    EXPECT_TRUE(s.found) << "no shutdown summary\n" << tail(log);
    // Every scan delivered ends in exactly one result.json.
    const auto all = read_results(out(), true);
    EXPECT_EQ(static_cast<long>(all.size()), s.scans) << s.line;
    long failed = 0;
    for (const auto& r : all) {
      failed += r.failed() ? 1 : 0;
      if (r.failed()) {
        EXPECT_FALSE(r.j.value("error", "").empty()) << r.path << ": " << r.j.dump(1);
      }
    }
    EXPECT_EQ(failed, s.failed) << "failed result.json files vs the summary: " << s.line;
    return s;
  }

  std::unique_ptr<ServeProcess> serve_;
};

// ------------------------------------------------------------------------------------------- attacks

// Issue items 1 and 2: a calibration serve cannot use (camera 65536 x 1024, which the wire accepts) (a) in a
// ScanBegin followed by a disconnect, (b) in a whole scan ending with ScanEnd, and (c) a 16385 x 64 camera in
// a small whole scan. Whether serve refuses it at the ScanBegin or fails at processing, each scan ends in
// exactly one failed result.json whose error names the bad size, logged as FAILED, and nothing else counts
// it (no protocol error).
TEST_F(ServeAttack, UnusableCalibrationEndsInOneFailedResult) {
  const OwnedScan& pyr = pyramid_scan();
  OwnedScan wide = pyr;
  wide.begin.calibration.camera.width = 65536;
  wide.begin.calibration.camera.height = 1024;
  OwnedScan odd = synthetic_scan(16, 64, 16385);
  const std::uint64_t a = 101, b = 102, c = 103;

  send_scan(scan_bytes(wide, a, true, 0, 0, false));  // ScanBegin, then the scanner is gone
  send_scan(scan_bytes(wide, b));
  send_scan(scan_bytes(odd, c));
  struct Want {
    std::uint64_t id;
    const char* names;
  };
  for (const Want& w : {Want{a, "65536"}, Want{b, "65536"}, Want{c, "16385"}}) {
    const auto r = wait_results(w.id);
    ASSERT_EQ(r.size(), 1u) << "scan " << w.id << "\n" << tail(serve().log());
    EXPECT_TRUE(r[0].failed()) << r[0].j.dump(1);
    EXPECT_NE(r[0].j.value("error", "").find(w.names), std::string::npos) << r[0].j.dump(1);
    bool logged = false;
    for (const auto& l : lines_with(serve().log(), "FAILED"))
      logged = logged || l.find("scan " + std::to_string(w.id) + " ") != std::string::npos;
    EXPECT_TRUE(logged) << "no FAILED line for scan " << w.id << "\n" << tail(serve().log());
  }
  const Summary s = finish();
  EXPECT_EQ(s.failed, 3) << s.line;
  EXPECT_EQ(s.protocol_errors, 0) << s.line;
  for (const std::uint64_t id : {a, b, c}) EXPECT_EQ(results_for(out(), id).size(), 1u) << "scan " << id;
}

// Issue item 3: a scan geometry whose processing cannot fit the memory budget is refused when its ScanBegin
// arrives: serve names the scan in its log before any stripe or ScanEnd is sent, its RSS stays under the
// budget, the scan ends in one failed result naming the budget, and serve goes on (heartbeats, SIGTERM). A
// scan it did not refuse is killed by the test at once (its processing would take gigabytes).
void huge_scan_is_refused_in_the_header(ServeAttack& t, ServeProcess& serve, const OwnedScan& huge,
                                        std::uint64_t id) {
  Client c(serve.port());
  ASSERT_TRUE(c.ok());
  Stream st;
  msg::ScanBegin b = huge.begin;
  b.scan_id = id;
  st.add(b);
  c.send(st.bytes);
  // Refused: the log names the scan (a FAILED result, a refusal or a protocol error) while the scanner has
  // sent nothing but the ScanBegin (and heartbeats, so that the link stays up).
  const std::string name = std::to_string(id);
  const bool refused = wait_until(
      serve,
      [&] {
        if (!c.host_closed()) {
          Stream hb(st.sequence());
          hb.heartbeat();
          c.send(hb.bytes);
          c.pump(50);
        }
        return serve.log().find(name) != std::string::npos;
      },
      seconds(10));
  if (!refused) {
    serve.kill_now();
    FAIL() << "ScanBegin of scan " << id << " (" << b.calibration.step_count << " steps, camera "
           << b.calibration.camera.width << " x " << b.calibration.camera.height
           << ") was not refused in the header (peak RSS " << mb(serve.peak_rss())
           << "); serve was killed before the scan could end (its processing would need gigabytes)\n"
           << tail(serve.log());
  }
  EXPECT_LT(serve.peak_rss(), rss_limit_bytes()) << "after the refused ScanBegin";
  // The rest of the scan (ignored or refused; the host may have closed the connection).
  Stream rest(st.sequence() + 1);
  for (const auto& s : huge.stripes) {
    msg::StripeHeader h = s.header;
    h.scan_id = id;
    rest.stripe(h, s.points);
  }
  msg::ScanEnd e = huge.end;
  e.scan_id = id;
  rest.add(e);
  c.send(rest.bytes);
  c.finish();
  ASSERT_TRUE(t.healthy("the refused scan " + name));
  // The refused scan ends in exactly one result, a failed one naming the budget.
  const auto r = t.wait_results(id);
  ASSERT_EQ(r.size(), 1u) << tail(serve.log());
  EXPECT_TRUE(r[0].failed()) << r[0].j.dump(1);
  EXPECT_NE(r[0].j.value("error", "").find("budget"), std::string::npos) << r[0].j.dump(1);
  const Summary s = t.finish();
  EXPECT_EQ(s.failed, 1) << "the refusal is not counted: " << s.line;
  EXPECT_EQ(s.protocol_errors, 0) << s.line;
}

TEST_F(ServeAttack, HugeScanIsRefusedInTheHeader) {
  huge_scan_is_refused_in_the_header(*this, serve(), synthetic_scan(65536, 16384), 301);
}

TEST_F(ServeAttack, HugeSensorIsRefusedInTheHeader) {
  huge_scan_is_refused_in_the_header(*this, serve(), synthetic_scan(500, 16384, 16384), 302);
}

// Issue item 5: a scanner streams a scan (the pyramid, 500 stripes over ~2.5 s) while another client
// connects every 50 ms. The streaming connection keeps its scan: every byte is accepted, the scanner gets the
// host's heartbeats, and the scan is recognized complete.
TEST_F(ServeAttack, StreamingScanIsNotEvictedByOtherClients) {
  const std::uint64_t id = 501;
  const Bytes bytes = scan_bytes(pyramid_scan(), id);
  Client scanner(serve().port());
  ASSERT_TRUE(scanner.ok());
  std::atomic<bool> streaming{true};
  std::atomic<int> intruders{0};
  std::thread intruder([&] {
    auto next = SteadyClock::now();
    while (streaming) {
      {
        Client c(serve().port());
        intruders += c.ok() ? 1 : 0;
        std::this_thread::sleep_for(milliseconds(25));
        c.pump();
      }
      next += milliseconds(50);
      std::this_thread::sleep_until(next);
    }
  });
  // 50 chunks, one every 50 ms.
  bool all_sent = true;
  const std::size_t chunk = bytes.size() / 50 + 1;
  for (std::size_t at = 0; at < bytes.size() && all_sent; at += chunk) {
    all_sent = scanner.send(std::span(bytes).subspan(at, std::min(chunk, bytes.size() - at)));
    scanner.pump(50);
  }
  streaming = false;
  intruder.join();
  ASSERT_TRUE(all_sent) << "serve closed the streaming scanner's connection after " << intruders.load()
                        << " other client(s) connected\n"
                        << tail(serve().log());
  EXPECT_GE(intruders.load(), 10);
  scanner.finish();
  EXPECT_GE(heartbeats_in(scanner.received()), 2) << "the streaming scanner got no host heartbeats";
  const auto r = wait_results(id);
  ASSERT_EQ(r.size(), 1u) << tail(serve().log());
  EXPECT_FALSE(r[0].failed()) << r[0].j.dump(1);
  EXPECT_EQ(r[0].status(), "complete") << r[0].j.dump(1);
  EXPECT_TRUE(r[0].j.contains("objects") && !r[0].j["objects"].empty()) << r[0].j.dump(1);
  const Summary s = finish();
  EXPECT_EQ(s.failed, 0) << s.line;
  EXPECT_EQ(s.protocol_errors, 0) << s.line;
}

// Issue item 6: a bad magic, a bad CRC, an oversize frame and a stripe claiming 10^6 points, each mid-scan on
// its own connection: each is logged with the peer's address and port and the reason, the connection is
// closed, the cut scan ends in one result ("connection closed for a protocol error"), and the summary counts
// 4 protocol errors.
TEST_F(ServeAttack, ProtocolErrorsAreLoggedWithThePeerAndCounted) {
  const OwnedScan& pyr = pyramid_scan();
  struct Attack {
    const char* what;
    const char* reason;  // in the logged reason
    std::function<Bytes(std::uint32_t seq)> frame;
  };
  const std::vector<Attack> attacks = {
      {"bad magic", "magic",
       [&](std::uint32_t seq) {
         Bytes f = frame_of(msg::Stripe{pyr.stripes[10].header,
                                        std::span<msg::StripePoint>(
                                            const_cast<msg::StripePoint*>(pyr.stripes[10].points.data()),
                                            pyr.stripes[10].points.size())},
                            seq);
         std::memcpy(f.data(), "XSWF", 4);
         return f;
       }},
      {"bad CRC", "CRC",
       [&](std::uint32_t seq) {
         msg::Heartbeat hb;
         Bytes f = frame_of(hb, seq);
         f[wire::kFrameHeaderSize + 3] ^= 0x40;
         return f;
       }},
      {"oversize frame", "payload length 1000000 exceeds",
       [&](std::uint32_t seq) {
         Bytes f = frame_of(msg::Heartbeat{}, seq);
         put_u32(f, 8, 1'000'000);
         f.resize(4096, 0x55);
         return f;
       }},
      {"stripe claiming 10^6 points", "point_count 1000000",
       [&](std::uint32_t seq) {
         msg::StripeHeader h = pyr.stripes[10].header;
         std::vector<msg::StripePoint> pts(20);
         Bytes f = frame_of(msg::Stripe{h, std::span<msg::StripePoint>(pts)}, seq);
         put_u32(f, wire::kFrameHeaderSize + wire::kStripeHeaderSize - 4, 1'000'000);
         fix_crc(f);
         return f;
       }},
  };
  std::uint64_t id = 601;
  for (const Attack& a : attacks) {
    SCOPED_TRACE(a.what);
    Bytes bytes = scan_bytes(pyr, id, true, 0, 10, false);
    const Bytes bad = a.frame(11);
    bytes.insert(bytes.end(), bad.begin(), bad.end());
    const Bytes more = scan_bytes(pyr, id, false, 10, 20, false, 12);
    bytes.insert(bytes.end(), more.begin(), more.end());
    const int port = send_scan(bytes, false);
    const std::string peer = "protocol error from 127.0.0.1:" + std::to_string(port);
    auto logged = [&] {
      std::vector<std::string> v;
      for (const auto& l : lines_with(serve().log(), peer)) {
        const std::size_t at = l.find(peer) + peer.size();  // the whole port, not a prefix of another
        if (at == l.size() || !std::isdigit(static_cast<unsigned char>(l[at]))) v.push_back(l);
      }
      return v;
    };
    ASSERT_TRUE(wait_until(serve(), [&] { return !logged().empty(); })) << "no '" << peer << "' in the log\n"
                                                                        << tail(serve().log());
    const auto lines = logged();
    ASSERT_EQ(lines.size(), 1u) << tail(serve().log());
    EXPECT_NE(lines[0].find(a.reason), std::string::npos) << lines[0];
    ++id;
  }
  for (std::uint64_t i = 601; i < id; ++i) {
    const auto r = wait_results(i);
    ASSERT_EQ(r.size(), 1u) << "scan " << i << "\n" << tail(serve().log());
    EXPECT_EQ(r[0].status(), "connection closed for a protocol error") << r[0].j.dump(1);
  }
  const Summary s = finish();
  EXPECT_EQ(s.protocol_errors, 4) << s.line;
}

// Issue item 7: the pyramid scan with two points on every row of every stripe (a second reflection 25 px
// away): all points are kept (the scan is complete, every stripe present) or the scan is refused with a
// true reason; never "missing stripes" for stripes that all arrived.
TEST_F(ServeAttack, StripesWithTwoPointsPerRowKeepEveryStripe) {
  OwnedScan twice = pyramid_scan();
  const double width = twice.begin.calibration.camera.width;
  for (auto& s : twice.stripes) {
    std::vector<msg::StripePoint> pts;
    for (const auto& p : s.points) {
      msg::StripePoint q = p;
      q.col = p.col + 25.0f < width - 1 ? p.col + 25.0f : p.col - 25.0f;
      q.peak = static_cast<std::uint16_t>(p.peak / 2);
      pts.push_back(p);
      pts.push_back(q);
    }
    s.points = std::move(pts);
  }
  const std::uint64_t id = 701;
  send_scan(scan_bytes(twice, id));
  const auto r = wait_results(id);
  ASSERT_EQ(r.size(), 1u) << tail(serve().log());
  EXPECT_NE(r[0].status(), "missing stripes") << r[0].j.dump(1);
  if (r[0].failed()) {
    EXPECT_EQ(r[0].j["error"].get<std::string>().find("missing"), std::string::npos) << r[0].j.dump(1);
  } else {
    EXPECT_EQ(r[0].status(), "complete") << r[0].j.dump(1);
    EXPECT_EQ(r[0].j["scan"]["stripes"], r[0].j["scan"]["steps"]) << r[0].j.dump(1);
  }
  const Summary s = finish();
  EXPECT_EQ(s.protocol_errors, 0) << s.line;
}

// ------------------------------------------------------------------------------------------- random

// One random connection: chunks of bytes (valid frames, mutated frames, garbage), stalls before some
// chunks, and how it ends.
struct RandomConnection {
  std::vector<Bytes> chunks;
  std::vector<int> stall_ms;  // before each chunk
  bool abrupt = false;        // RST instead of FIN
  bool protocol_error = false;
  std::string ops;
};

// True when the project's decoder refuses these bytes (what serve counts as a protocol error). A frame cut
// at the end is not an error: the stream just ended.
bool has_protocol_error(const Bytes& bytes) {
  wire::FrameDecoder dec("simulated");
  wire::DecodedMessage m;
  wire::FrameView f;
  try {
    for (std::span<const std::uint8_t> in(bytes); !in.empty();) {
      in = in.subspan(dec.feed(in));
      while (dec.next(f)) wire::decode(f, m, dec.source());
    }
    while (dec.next(f)) wire::decode(f, m, dec.source());
  } catch (const fs::Error&) {
    return true;
  }
  return false;
}

class RandomScanner {
 public:
  explicit RandomScanner(std::uint64_t seed) : rng_(seed) {}

  RandomConnection next() {
    RandomConnection c;
    Stream st(pick(0, 3) == 0 ? pick(0, 1000) : 0);
    const int ops = pick(1, 16);
    // About half the connections carry one malformed piece (the rest stay valid and make scans).
    const int bad_at = pick(0, 99) < 45 ? pick(0, ops - 1) : -1;
    for (int i = 0; i < ops; ++i) {
      int stall = 0;
      if (i == bad_at) {
        switch (pick(0, 3)) {
          case 0: {
            c.ops += "g";  // garbage
            Bytes g(static_cast<std::size_t>(pick(1, 64)));
            for (auto& b : g) b = static_cast<std::uint8_t>(pick(0, 255));
            st.raw(g);
            break;
          }
          case 1: {
            c.ops += "x";  // bit flips, CRC left as is
            Bytes f = any_frame(st.sequence());
            for (int n = pick(1, 3); n > 0; --n)
              f[static_cast<std::size_t>(pick(0, int(f.size()) - 1))] ^=
                  static_cast<std::uint8_t>(pick(1, 255));
            st.raw(f);
            break;
          }
          case 2:
            c.ops += "p";  // payload damage under a valid CRC: reaches the payload decoder
            st.raw(crc_valid_damage(st.sequence()));
            break;
          default: {
            c.ops += "h";  // header damage: length, version, type
            Bytes f = frame_of(msg::Heartbeat{}, st.sequence());
            switch (pick(0, 2)) {
              case 0:
                put_u32(f, 8, static_cast<std::uint32_t>(pick(98'353, std::numeric_limits<int>::max())));
                break;
              case 1:
                f[4] = static_cast<std::uint8_t>(pick(2, 255));
                break;
              default:
                f[6] = static_cast<std::uint8_t>(pick(0, 1) == 0 ? 0 : pick(6, 255));
                break;
            }
            st.raw(f);
            break;
          }
        }
      } else {
        const int k = pick(0, 99);
        if (k < 18) {
          c.ops += "B";
          st.add(scan_begin());
        } else if (k < 70) {
          c.ops += "S";
          st.stripe(stripe_header(), points());
        } else if (k < 82) {
          c.ops += "E";
          st.add(scan_end());
        } else if (k < 90) {
          c.ops += "H";
          st.heartbeat();
        } else if (k < 93) {
          c.ops += "F";
          msg::Fault f;
          f.code = static_cast<std::uint32_t>(pick(0, 1 << 20));
          f.text = std::string(static_cast<std::size_t>(pick(0, 256)), static_cast<char>(pick(32, 126)));
          st.add(f);
        } else {
          c.ops += "_";  // a stall before the next bytes
          stall = pick(1, 60);
        }
      }
      if (!st.bytes.empty() || stall > 0) {
        c.chunks.push_back(std::move(st.bytes));
        c.stall_ms.push_back(stall);
        st.bytes.clear();
      }
    }
    Bytes all;
    for (const auto& ch : c.chunks) all.insert(all.end(), ch.begin(), ch.end());
    const int end = pick(0, 99);
    if (end < 15 && !all.empty()) {
      c.ops += "|cut";  // the last frame cut short
      Bytes f = scan_end_frame(st.sequence());
      f.resize(static_cast<std::size_t>(pick(1, int(f.size()) - 1)));
      all.insert(all.end(), f.begin(), f.end());
      c.chunks.push_back(std::move(f));
      c.stall_ms.push_back(0);
    }
    c.protocol_error = has_protocol_error(all);
    if (end >= 85 && !c.protocol_error) {
      c.ops += "|rst";
      c.abrupt = true;
    }
    return c;
  }

 private:
  int pick(int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng_); }
  std::uint64_t scan_id() {
    return pick(0, 9) == 0 ? rng_() : 900'000 + static_cast<std::uint64_t>(pick(0, 3));
  }

  msg::ScanBegin scan_begin() {
    msg::ScanBegin b;
    b.scan_id = scan_id();
    id_ = b.scan_id;
    steps_ = static_cast<std::uint32_t>(pick(1, 48));
    first_ = pick(-5, 100);
    rows_ = static_cast<std::uint32_t>(pick(8, 64));
    cols_ = static_cast<std::uint32_t>(pick(16, 96));
    b.calibration = fs::ScannerCalibration::bench_default(steps_);
    b.calibration.first_step = first_;
    b.calibration.camera.width = cols_;
    b.calibration.camera.height = rows_;
    b.calibration.camera.cx = cols_ / 2.0;
    b.calibration.camera.cy = rows_ / 2.0;
    b.calibration.camera.fx = b.calibration.camera.fy = 1600.0 * cols_ / 1280.0;
    b.scanner_model = std::string(static_cast<std::size_t>(pick(0, 64)), 'm');
    b.pixel_bits = pick(0, 1) ? 8 : 16;
    return b;
  }
  msg::StripeHeader stripe_header() {
    msg::StripeHeader h;
    h.scan_id = pick(0, 4) == 0 ? scan_id() : id_;
    h.step_index = static_cast<std::uint32_t>(first_ + pick(-3, int(steps_) + 3));
    h.commanded_angle = pick(-100, 100) / 100.0;
    h.measured_position = pick(0, 9) == 0 ? std::numeric_limits<double>::quiet_NaN() : h.step_index;
    h.frame_sequence = static_cast<std::uint32_t>(pick(0, 1000));
    h.flags = static_cast<std::uint32_t>(pick(0, 3));
    return h;
  }
  std::vector<msg::StripePoint> points() {
    std::vector<msg::StripePoint> v(
        static_cast<std::size_t>(pick(0, 9) == 0 ? pick(0, 600) : pick(0, 2 * int(rows_))));
    for (auto& p : v) {
      p.row = static_cast<std::uint16_t>(pick(0, int(rows_) + 4));
      const int kind = pick(0, 49);
      p.col = kind == 0   ? std::numeric_limits<float>::quiet_NaN()
              : kind == 1 ? std::numeric_limits<float>::infinity()
              : kind == 2 ? -1e30f
                          : float(pick(-500, int(cols_) * 100 + 500)) / 100.0f;
      p.peak = static_cast<std::uint16_t>(pick(0, 65535));
      p.width = float(pick(0, 1000)) / 100.0f;
    }
    return v;
  }
  msg::ScanEnd scan_end() {
    msg::ScanEnd e;
    e.scan_id = pick(0, 4) == 0 ? scan_id() : id_;
    e.stripes_sent = static_cast<std::uint32_t>(pick(0, 60));
    e.completed = static_cast<std::uint8_t>(pick(0, 3) == 0 ? 0 : 1);
    return e;
  }
  Bytes scan_end_frame(std::uint32_t seq) { return frame_of(scan_end(), seq); }
  Bytes any_frame(std::uint32_t seq) {
    switch (pick(0, 3)) {
      case 0:
        return frame_of(scan_begin(), seq);
      case 1: {
        auto pts = points();
        return frame_of(msg::Stripe{stripe_header(), std::span<msg::StripePoint>(pts)}, seq);
      }
      case 2:
        return frame_of(scan_end(), seq);
      default:
        return frame_of(msg::Heartbeat{}, seq);
    }
  }
  // A Stripe / ScanEnd / Fault / Heartbeat frame whose payload is damaged, with its CRC made valid again:
  // a lying point count, a payload cut or lengthened, a frame type that does not fit the payload, a string
  // length beyond the payload. (ScanBegin calibrations are left alone: what serve does with a decodable but
  // absurd calibration is the budget tests' business.)
  Bytes crc_valid_damage(std::uint32_t seq) {
    Bytes f;
    switch (pick(0, 4)) {
      case 0: {  // point count
        auto pts = points();
        f = frame_of(msg::Stripe{stripe_header(), std::span<msg::StripePoint>(pts)}, seq);
        put_u32(f, wire::kFrameHeaderSize + wire::kStripeHeaderSize - 4,
                static_cast<std::uint32_t>(pick(0, 3) == 0 ? pick(0, 20)
                                                           : pick(0, std::numeric_limits<int>::max())));
        break;
      }
      case 1: {  // payload shortened or lengthened
        f = frame_of(pick(0, 1) ? msg::Heartbeat{} : msg::Heartbeat{1, 2, 3}, seq);
        const std::size_t payload = f.size() - wire::kFrameOverhead;
        const std::size_t n = static_cast<std::size_t>(pick(0, int(payload) + 8));
        f.resize(wire::kFrameHeaderSize + n + wire::kFrameCrcSize, 0);
        put_u32(f, 8, static_cast<std::uint32_t>(n));
        break;
      }
      case 2: {  // a type that does not fit the payload
        f = frame_of(scan_end(), seq);
        f[6] = static_cast<std::uint8_t>(pick(1, 5));
        break;
      }
      case 3: {  // a Fault whose text length lies
        msg::Fault ft;
        ft.text = "fault";
        f = frame_of(ft, seq);
        f[wire::kFrameHeaderSize + 4] = static_cast<std::uint8_t>(pick(0, 255));
        f[wire::kFrameHeaderSize + 5] = static_cast<std::uint8_t>(pick(0, 255));
        break;
      }
      default: {  // a newer minor version with extra payload (accepted)
        f = frame_of(msg::Heartbeat{}, seq);
        f[5] = static_cast<std::uint8_t>(pick(1, 9));
        f.insert(f.end() - wire::kFrameCrcSize, 5, 0xab);
        put_u32(f, 8, static_cast<std::uint32_t>(f.size() - wire::kFrameOverhead));
        break;
      }
    }
    fix_crc(f);
    return f;
  }

  std::mt19937_64 rng_;
  std::uint64_t id_ = 900'000;
  std::uint32_t steps_ = 10, rows_ = 16, cols_ = 32;
  std::int32_t first_ = 0;
};

// Random frame sequences over many connections, one after another (each connection is read to its end by
// serve before the next one starts, so that the protocol errors are exactly those the project's decoder
// finds in the bytes sent). Health checks every 50 connections; at the end the valid scan, the summary's
// protocol error count, and one result.json per delivered scan.
TEST_F(ServeAttack, RandomFrameSequences) {
  const int rounds = env_int("FACETSCAN_ATTACK_ROUNDS", 200);
  const auto seed = static_cast<std::uint64_t>(env_int("FACETSCAN_ATTACK_SEED", 25));
  std::printf("[ RANDOM   ] %d connections, seed %llu (FACETSCAN_ATTACK_ROUNDS, FACETSCAN_ATTACK_SEED)\n",
              rounds, static_cast<unsigned long long>(seed));
  RandomScanner gen(seed);
  long expected_errors = 0;
  const auto start = SteadyClock::now();
  for (int i = 0; i < rounds; ++i) {
    const RandomConnection rc = gen.next();
    SCOPED_TRACE("connection " + std::to_string(i) + ": " + rc.ops);
    expected_errors += rc.protocol_error ? 1 : 0;
    Client c(serve().port());
    ASSERT_TRUE(c.ok()) << "connection " << i << " refused\n" << tail(serve().log());
    for (std::size_t k = 0; k < rc.chunks.size(); ++k) {
      if (rc.stall_ms[k] > 0) std::this_thread::sleep_for(milliseconds(rc.stall_ms[k]));
      if (!c.send(rc.chunks[k], static_cast<std::size_t>(1 + i % 97))) break;  // the host closed it
    }
    if (rc.abrupt) {
      c.abort();
    } else {
      ASSERT_TRUE(c.finish()) << "serve did not close connection " << i << "\n" << tail(serve().log());
    }
    if ((i + 1) % 50 == 0) {
      ASSERT_TRUE(healthy("random connection " + std::to_string(i)));
    }
  }
  const double secs = std::chrono::duration<double>(SteadyClock::now() - start).count();
  std::printf("[ RANDOM   ] %d connections in %.1f s, %ld with a protocol error\n", rounds, secs,
              expected_errors);
  const Summary s = finish();
  std::printf("[ RANDOM   ] %s\n", s.line.c_str());
  EXPECT_EQ(s.protocol_errors, expected_errors) << s.line;
  for (const auto& r : read_results(out()))
    EXPECT_NE(r.status(), "in progress") << r.path << ": " << r.j.dump(1);
}

}  // namespace
