// The web view's API without a browser: shapes, status codes, traversal attempts, bounds, concurrency.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "host/recognize/report.hpp"
#include "host/web/api.hpp"
#include "host/web/event_hub.hpp"
#include "host/web/http_server.hpp"
#include "host/web/report_view.hpp"
#include "host/web/scan_history.hpp"

namespace fs::host::web {
namespace {

namespace stdfs = std::filesystem;

struct Reply {
  int status = 0;
  std::string head, body;
};

int connect_to(std::uint16_t port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  timeval tv{10, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(port);
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

// One raw request (the target is sent exactly as given: no client-side normalization or encoding).
Reply request(std::uint16_t port, const std::string& target, const std::string& method = "GET") {
  Reply r;
  const int fd = connect_to(port);
  if (fd < 0) return r;
  const std::string req = method + " " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
  if (::send(fd, req.data(), req.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(req.size())) {
    ::close(fd);
    return r;
  }
  std::string all;
  char buf[65536];
  for (ssize_t n; (n = ::recv(fd, buf, sizeof buf, 0)) > 0;) all.append(buf, static_cast<std::size_t>(n));
  ::close(fd);
  const auto split = all.find("\r\n\r\n");
  if (all.rfind("HTTP/1.1 ", 0) != 0 || split == std::string::npos) return r;
  r.status = std::stoi(all.substr(9, 3));
  r.head = all.substr(0, split);
  r.body = all.substr(split + 4);
  return r;
}

std::shared_ptr<ScanRecord> fake_record(std::uint64_t id, const stdfs::path& dir) {
  auto r = std::make_shared<ScanRecord>();
  r->id = id;
  r->scan_id = 100 + id;
  r->summary_json =
      nlohmann::json{{"id", id}, {"scan_id", 100 + id}, {"objects", nlohmann::json::array()}}.dump();
  r->detail_json = nlohmann::json{{"scan", {{"id", id}}}, {"objects", nlohmann::json::array()}}.dump();
  OrganizedCloud c;
  c.reset(4, 3);
  for (std::uint32_t row = 0; row < 3; ++row)
    for (std::uint32_t col = 0; col < 4; ++col) c.at(row, col) = Eigen::Vector3f(col, row, 1.0f + row);
  r->points = points_blob(c, std::vector<std::int32_t>(12, 0), std::vector<std::int32_t>(12, 2));
  r->dir = dir;
  return r;
}

class WebServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = stdfs::temp_directory_path() / ("fs-web-test-" + std::to_string(::getpid()));
    stdfs::remove_all(root_);
    stdfs::create_directories(root_ / "scan" / "report");
    std::ofstream(root_ / "scan" / "report" / "index.html") << "<html>report</html>";
    std::ofstream(root_ / "scan" / "result.json") << "{}";
    std::ofstream(root_ / "secret.txt") << "TOP-SECRET";
    stdfs::create_symlink(root_ / "secret.txt", root_ / "scan" / "link.txt");
    WebOptions o;
    o.listen = "127.0.0.1:0";
    o.max_event_clients = 3;
    o.threads = 8;
    o.max_connections = kMaxConnections;
    o.history = 4;
    server_ = std::make_unique<WebServer>(o);
    server_->start();
    server_->publish_scan(fake_record(1, root_ / "scan"));
  }
  void TearDown() override {
    server_.reset();
    stdfs::remove_all(root_);
  }
  static constexpr int kMaxConnections = 48;
  stdfs::path root_;
  std::unique_ptr<WebServer> server_;
};

TEST_F(WebServerTest, PageAssetsAndJsonShapes) {
  const auto port = server_->port();
  Reply r = request(port, "/");
  EXPECT_EQ(r.status, 200);
  EXPECT_NE(r.body.find("id=\"view\""), std::string::npos);
  EXPECT_NE(r.body.find("/static/three.min.js"), std::string::npos);
  EXPECT_NE(r.head.find("Content-Security-Policy"), std::string::npos);
  for (const char* a : {"/static/three.min.js", "/static/OrbitControls.js", "/static/view3d.js",
                        "/static/app.js", "/static/style.css"})
    EXPECT_EQ(request(port, a).status, 200) << a;
  EXPECT_EQ(request(port, "/static/../CMakeLists.txt").status, 404);
  EXPECT_EQ(request(port, "/static/nothing.js").status, 404);

  r = request(port, "/api/status");
  ASSERT_EQ(r.status, 200);
  const auto s = nlohmann::json::parse(r.body);
  for (const char* k : {"connected", "scanning", "recognizing", "stripes", "steps", "stripes_per_s", "faults",
                        "loop", "web", "latest_scan"})
    EXPECT_TRUE(s.contains(k)) << k;
  EXPECT_EQ(s["latest_scan"], 1);

  r = request(port, "/api/scans");
  ASSERT_EQ(r.status, 200);
  const auto l = nlohmann::json::parse(r.body);
  ASSERT_EQ(l["scans"].size(), 1u);
  EXPECT_EQ(l["scans"][0]["id"], 1);
  EXPECT_EQ(l["capacity"], 4);

  r = request(port, "/api/scans/1");
  ASSERT_EQ(r.status, 200);
  EXPECT_EQ(nlohmann::json::parse(r.body)["scan"]["id"], 1);
  r = request(port, "/api/scans/1/points");
  ASSERT_EQ(r.status, 200);
  ASSERT_GE(r.body.size(), kPointsHeader);
  EXPECT_EQ(r.body.substr(0, 4), "FSPT");
  EXPECT_NE(r.head.find("application/octet-stream"), std::string::npos);

  EXPECT_EQ(request(port, "/api/scans/2").status, 404);
  EXPECT_EQ(request(port, "/api/scans/abc").status, 400);
  EXPECT_EQ(request(port, "/api/scans/-1").status, 400);
  EXPECT_EQ(request(port, "/api/scans/99999999999999999999999").status, 400);
  EXPECT_EQ(request(port, "/api/scans/01").status, 400) << "leading zero";
  EXPECT_EQ(request(port, "/api/scans/001/points").status, 400) << "leading zeros";
  EXPECT_EQ(request(port, "/api/scans/0").status, 404) << "0 itself is an ID (none such)";
  EXPECT_EQ(request(port, "/api/nothing").status, 404);
  EXPECT_EQ(nlohmann::json::parse(request(port, "/api/nothing").body)["status"], 404);
}

TEST_F(WebServerTest, ReadOnly) {
  for (const char* m : {"POST", "PUT", "DELETE", "PATCH"}) {
    const Reply r = request(server_->port(), "/api/status", m);
    EXPECT_EQ(r.status, 405) << m;
    EXPECT_NE(r.head.find("Allow: GET, HEAD"), std::string::npos) << m;
  }
}

TEST_F(WebServerTest, ScanFilesWithoutTraversal) {
  const auto port = server_->port();
  Reply r = request(port, "/scans/1/files/report/index.html");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.body, "<html>report</html>");
  EXPECT_EQ(request(port, "/scans/1/files/result.json").status, 200);
  EXPECT_EQ(request(port, "/scans/1/recording.fscan").status, 404);  // none
  for (const char* t :
       {"/scans/1/files/../secret.txt", "/scans/1/files/report/../../secret.txt",
        "/scans/1/files/%2e%2e/secret.txt", "/scans/1/files/%2E%2E%2Fsecret.txt",
        "/scans/1/files/..%2fsecret.txt", "/scans/1/files/..%5csecret.txt",
        "/scans/1/files/%252e%252e/secret.txt", "/scans/1/files/....//secret.txt",
        "/scans/1/files//etc/passwd", "/scans/1/files/%2fetc%2fpasswd", "/scans/1/files/report/./index.html",
        "/scans/1/files/report%00.html", "/scans/1/files/link.txt", "/scans/1/files/",
        "/scans/1/files/report", "/scans/..%2f..%2fsecret.txt/files/x", "/%2e%2e/%2e%2e/etc/passwd",
        "/../../etc/passwd", "/static/..%2f..%2fetc%2fpasswd"}) {
    r = request(port, t);
    EXPECT_TRUE(r.status == 404 || r.status == 400) << t << " -> " << r.status;
    EXPECT_EQ(r.body.find("TOP-SECRET"), std::string::npos) << t;
    EXPECT_EQ(r.body.find("root:"), std::string::npos) << t;
  }
}

TEST(ResolveUnder, RejectsEveryEscape) {
  const stdfs::path root = stdfs::temp_directory_path() / ("fs-web-resolve-" + std::to_string(::getpid()));
  stdfs::create_directories(root / "a");
  std::ofstream(root / "a" / "f.txt") << "x";
  EXPECT_TRUE(resolve_under(root, "a/f.txt"));
  for (const char* bad : {"", "/a/f.txt", "../a/f.txt", "a/../a/f.txt", "a//f.txt", "./a/f.txt", "a/f.txt/",
                          "a\\f.txt", "a/%2e%2e/f.txt", "a", "nothing"})
    EXPECT_FALSE(resolve_under(root, bad)) << bad;
  EXPECT_FALSE(resolve_under(root, std::string_view("a/f.txt\0x", 9)));
  stdfs::remove_all(root);
}

TEST_F(WebServerTest, HundredConcurrentClients) {
  const auto port = server_->port();
  std::atomic<int> ok{0}, busy{0}, other{0};
  std::vector<std::thread> clients;
  for (int i = 0; i < 100; ++i)
    clients.emplace_back([&, i] {
      const Reply r = request(port, i % 2 ? "/api/status" : "/api/scans/1/points");
      (r.status == 200 ? ok : r.status == 503 ? busy : other)++;
    });
  for (auto& t : clients) t.join();
  EXPECT_EQ(other.load(), 0) << "every client got 200 or 503 (no hang, no reset)";
  // A connection is answered 503 only when kMaxConnections others are open or waiting at its accept, so the
  // first kMaxConnections accepted are always served, however the 100 interleave.
  EXPECT_GE(ok.load(), std::min(kMaxConnections, 100));
  EXPECT_EQ(ok.load() + busy.load(), 100);
  EXPECT_EQ(server_->stats().rejected_busy, static_cast<std::uint64_t>(busy.load()))
      << "every 503 is the limit's";
  EXPECT_EQ(request(port, "/api/status").status, 200) << "still serving afterwards";
}

// Reads from an event stream until `needle` or the timeout.
bool read_until(int fd, const std::string& needle, std::string& got) {
  char buf[4096];
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (got.find(needle) == std::string::npos && std::chrono::steady_clock::now() < until) {
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) return false;
    got.append(buf, static_cast<std::size_t>(n));
  }
  return got.find(needle) != std::string::npos;
}

TEST_F(WebServerTest, EventsArePushedAndClientsBounded) {
  const auto port = server_->port();
  const std::string req = "GET /api/events HTTP/1.1\r\nHost: x\r\n\r\n";
  std::vector<int> fds;
  for (int i = 0; i < 3; ++i) {
    fds.push_back(connect_to(port));
    ASSERT_GE(fds.back(), 0);
    ASSERT_EQ(::send(fds.back(), req.data(), req.size(), MSG_NOSIGNAL), static_cast<ssize_t>(req.size()));
    std::string got;
    // A new client gets the latest status and scan at once.
    EXPECT_TRUE(read_until(fds.back(), "event: scan", got)) << got;
    EXPECT_NE(got.find("text/event-stream"), std::string::npos);
  }
  EXPECT_EQ(request(port, "/api/events").status, 503) << "beyond max_event_clients";
  LiveStatus s;
  s.stripes = 321;
  s.steps = 500;
  server_->publish_status(s);
  server_->publish_scan(fake_record(2, root_ / "scan"));
  for (int fd : fds) {
    std::string got;
    EXPECT_TRUE(read_until(fd, "\"stripes\":321", got)) << got;
    EXPECT_TRUE(read_until(fd, "\"id\":2", got)) << got;
    ::close(fd);
  }
  // Freed slots are reused once the server notices the closed streams (next write: keep-alive or event).
  bool reopened = false;
  for (int i = 0; i < 50 && !reopened; ++i) {
    server_->publish_status(s);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    reopened = server_->stats().event_clients < 3;
  }
  EXPECT_TRUE(reopened);
}

TEST_F(WebServerTest, AStalledClientNeverBlocksThePublisher) {
  const auto port = server_->port();
  const int fd = connect_to(port);  // subscribes and then never reads
  const std::string req = "GET /api/events HTTP/1.1\r\nHost: x\r\n\r\n";
  ASSERT_EQ(::send(fd, req.data(), req.size(), MSG_NOSIGNAL), static_cast<ssize_t>(req.size()));
  for (int i = 0; i < 100 && server_->stats().event_clients == 0; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ASSERT_EQ(server_->stats().event_clients, 1u);
  // 200 MB of events to a client that reads nothing: publish returns every time (the queue drops the oldest).
  const std::string big(1 << 20, 'x');
  for (int i = 0; i < 200; ++i) {
    auto r = fake_record(10 + static_cast<std::uint64_t>(i), root_ / "scan");
    r->summary_json = "\"" + big + "\"";
    server_->publish_scan(std::move(r));
  }
  EXPECT_GT(server_->stats().events_dropped, 0u);
  EXPECT_LE(server_->stats().history, 4u) << "history bounded";
  EXPECT_EQ(request(port, "/api/status").status, 200) << "others are still served";
  ::close(fd);
}

TEST(EventHub, CoalescesDropsAndBounds) {
  EventHub hub(2, 3);
  auto a = hub.subscribe();
  auto b = hub.subscribe();
  ASSERT_TRUE(a && b);
  EXPECT_FALSE(hub.subscribe()) << "bounded";
  for (int i = 0; i < 10; ++i) hub.publish("status", std::to_string(i), true);
  std::vector<Event> ev;
  ASSERT_TRUE(hub.next(*a, ev, std::chrono::milliseconds(0)));
  ASSERT_EQ(ev.size(), 1u) << "coalesced";
  EXPECT_EQ(*ev[0].data, "9");
  for (int i = 0; i < 10; ++i) hub.publish("scan", std::to_string(i), false);
  ev.clear();
  ASSERT_TRUE(hub.next(*a, ev, std::chrono::milliseconds(0)));
  ASSERT_EQ(ev.size(), 3u) << "queue bound";
  EXPECT_EQ(*ev.back().data, "9");
  EXPECT_GT(hub.dropped(), 0u);
  hub.unsubscribe(b);
  auto c = hub.subscribe();
  ASSERT_TRUE(c);
  ev.clear();
  ASSERT_TRUE(hub.next(*c, ev, std::chrono::milliseconds(0)));
  EXPECT_EQ(ev.size(), 2u) << "a new subscriber gets the latest of each kind";
  hub.close();
  EXPECT_FALSE(hub.next(*c, ev, std::chrono::milliseconds(10)));
}

TEST(ScanHistory, KeepsTheLastN) {
  ScanHistory h(3);
  for (std::uint64_t i = 1; i <= 5; ++i) h.add(fake_record(i, {}));
  EXPECT_EQ(h.size(), 3u);
  EXPECT_FALSE(h.find(2));
  EXPECT_TRUE(h.find(3));
  EXPECT_EQ(h.latest()->id, 5u);
  EXPECT_EQ(h.newest_first().front()->id, 5u);
}

TEST(PointsBlob, FormatAndDownsampling) {
  OrganizedCloud c;
  c.reset(100, 100);
  for (std::uint32_t row = 0; row < 100; ++row)
    for (std::uint32_t col = 0; col < 100; ++col)
      if ((row + col) % 7) c.at(row, col) = Eigen::Vector3f(col, row, 0.5f * col);
  std::vector<std::int32_t> obj(c.size(), -1), reg(c.size(), 3);
  obj[c.index(0, 1)] = 2;
  const std::string b = points_blob(c, obj, reg, 1000);
  std::uint32_t n = 0, flags = 0;
  std::memcpy(&n, b.data() + 8, 4);
  std::memcpy(&flags, b.data() + 12, 4);
  EXPECT_LE(n, 1000u);
  EXPECT_GT(n, 200u);
  EXPECT_EQ(flags, 1u);
  const std::size_t obj_off = kPointsHeader + 12 * n, reg_off = (obj_off + n + 1) / 2 * 2;
  EXPECT_EQ(b.size(), reg_off + 2 * n);
  std::uint16_t r0 = 0;
  std::memcpy(&r0, b.data() + reg_off, 2);
  EXPECT_EQ(r0, 3);

  // Without region ids (flags 0) the blob ends after the object bytes.
  const std::string nb = points_blob(c, obj, {}, 1000);
  std::memcpy(&n, nb.data() + 8, 4);
  std::memcpy(&flags, nb.data() + 12, 4);
  EXPECT_EQ(flags, 0u);
  EXPECT_EQ(nb.size(), kPointsHeader + 13 * n);

  // At most max_points also when the valid points are not spread evenly (only every other row and column: the
  // stride guessed from the valid count keeps all of them).
  OrganizedCloud sparse;
  sparse.reset(100, 100);
  for (std::uint32_t row = 0; row < 100; row += 2)
    for (std::uint32_t col = 0; col < 100; col += 2) sparse.at(row, col) = Eigen::Vector3f(col, row, 1.0f);
  const std::string sb = points_blob(sparse, {}, {}, 1000);
  std::memcpy(&n, sb.data() + 8, 4);
  EXPECT_LE(n, 1000u);
  EXPECT_GT(n, 250u);
  EXPECT_EQ(sb.size(), kPointsHeader + 13 * n);

  EXPECT_EQ(rec::base64("Man"), "TWFu");
  EXPECT_EQ(rec::base64("Ma"), "TWE=");
  EXPECT_EQ(rec::base64("M"), "TQ==");
}

}  // namespace
}  // namespace fs::host::web
