// End-to-end: runs the built binaries (build/bin/facetscan, facetscan-fw) as a user would.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "support/test_paths.hpp"

namespace {

namespace stdfs = std::filesystem;

struct CmdResult {
  int code = -1;
  std::string out;
};

CmdResult run(const std::string& cmd) {
  CmdResult r;
  FILE* p = popen((cmd + " 2>&1").c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf{};
  std::size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.out.append(buf.data(), n);
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::string bin(const std::string& name) { return (fs::test::bin_dir() / name).string(); }

stdfs::path temp_dir(const std::string& name) {
  const stdfs::path d = stdfs::temp_directory_path() / ("facetscan-e2e-" + name + "-" + std::to_string(getpid()));
  stdfs::remove_all(d);
  stdfs::create_directories(d);
  return d;
}

nlohmann::json read_json(const stdfs::path& p) {
  std::ifstream f(p);
  return nlohmann::json::parse(f);
}

// The truncated pyramid of hw-sim/scenes/pyramid.json (at the origin, unrotated) is found, once, in its pose.
void expect_pyramid(const nlohmann::json& j) {
  ASSERT_EQ(j["objects"].size(), 1u) << j.dump(1);
  const auto& o = j["objects"][0];
  EXPECT_EQ(o["model"], "truncated_pyramid");
  EXPECT_GE(o["confidence"].get<double>(), 0.6);   // the recognizer's acceptance threshold
}

// One shared demo run (the scan it records feeds the offline tests).
const stdfs::path& demo_dir() {
  static const stdfs::path dir = [] {
    const stdfs::path d = temp_dir("demo");
    const CmdResult r = run(bin("facetscan") + " demo --scene pyramid -q -o " + d.string());
    EXPECT_EQ(r.code, 0) << r.out;
    return d;
  }();
  return dir;
}

TEST(EndToEnd, DemoOverTcpLoopbackRecognizesThePyramid) {
  const stdfs::path d = demo_dir();
  ASSERT_TRUE(stdfs::exists(d / "scan.fscan"));
  stdfs::path result;
  for (const auto& e : stdfs::recursive_directory_iterator(d))
    if (e.path().filename() == "result.json") result = e.path();
  ASSERT_FALSE(result.empty()) << "no result.json under " << d;
  const nlohmann::json j = read_json(result);
  expect_pyramid(j);
  EXPECT_FALSE(j["scan"]["partial"].get<bool>());
  EXPECT_TRUE(stdfs::exists(result.parent_path() / "report" / "index.html"));
  EXPECT_TRUE(stdfs::exists(result.parent_path() / "report" / "segmentation.png"));
}

TEST(EndToEnd, OfflineRecognitionOfTheRecordedScan) {
  const stdfs::path d = demo_dir();
  const std::string lib = (fs::test::source_dir() / "hw-sim/scenes/meshes").string();
  const CmdResult r = run(bin("facetscan") + " recognize " + (d / "scan.fscan").string() + " -l " + lib +
                    " -q --json " + (d / "offline.json").string());
  ASSERT_EQ(r.code, 0) << r.out;
  expect_pyramid(read_json(d / "offline.json"));
}

TEST(EndToEnd, OfflineRecognitionOfExportedPcd) {
  const stdfs::path d = demo_dir();
  const std::string lib = (fs::test::source_dir() / "hw-sim/scenes/meshes").string();
  for (const std::string ext : {"pcd"}) {
    const stdfs::path cloud = d / ("cloud." + ext);
    CmdResult r = run(bin("facetscan") + " export " + (d / "scan.fscan").string() + " -o " + cloud.string());
    ASSERT_EQ(r.code, 0) << r.out;
    // Exported clouds are in millimetres; a laser scan is segmented with the laser profile.
    r = run(bin("facetscan") + " recognize " + cloud.string() + " -l " + lib + " --segment laser --scale 1 -q --json " +
            (d / ("offline-" + ext + ".json")).string());
    ASSERT_EQ(r.code, 0) << r.out;
    expect_pyramid(read_json(d / ("offline-" + ext + ".json")));
  }
}

TEST(EndToEnd, BatchOverADirectoryWritesASummary) {
  const stdfs::path d = demo_dir();
  const stdfs::path in = temp_dir("batch");
  stdfs::copy_file(d / "scan.fscan", in / "a.fscan");
  std::ofstream(in / "broken.pcd") << "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\n";
  const std::string lib = (fs::test::source_dir() / "hw-sim/scenes/meshes").string();
  const CmdResult r = run(bin("facetscan") + " recognize " + in.string() + " -l " + lib + " -q --summary-csv " +
                    (in / "summary.csv").string());
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream f(in / "summary.csv");
  const std::string csv((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  EXPECT_NE(csv.find("a.fscan,ok,1,truncated_pyramid"), std::string::npos) << csv;
  EXPECT_NE(csv.find("broken.pcd,error"), std::string::npos) << csv;
}

// A scanner that dies mid-scan: serve reports the partial scan, then recognizes the next full one.
TEST(EndToEnd, ServeSurvivesAScannerDisconnectingMidScan) {
  const stdfs::path d = demo_dir();
  const stdfs::path out = temp_dir("serve");
  std::ifstream f(d / "scan.fscan", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 1000u);
  const std::string frames = bytes.substr(16);   // the .fscan file header is 16 bytes; the rest is the stream
  const std::string lib = (fs::test::source_dir() / "hw-sim/scenes/meshes").string();
  // Port: pick a free one.
  int probe = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(bind(probe, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  socklen_t len = sizeof a;
  getsockname(probe, reinterpret_cast<sockaddr*>(&a), &len);
  const int port = ntohs(a.sin_port);
  close(probe);
  std::thread server([&] {
    const CmdResult r = run(bin("facetscan") + " serve --listen 127.0.0.1:" + std::to_string(port) + " -l " + lib +
                      " --max-scans 2 -o " + out.string());
    EXPECT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("PARTIAL"), std::string::npos) << r.out;
  });
  auto send_stream = [&](std::size_t n) {
    for (int attempt = 0; attempt < 200; ++attempt) {
      const int s = socket(AF_INET, SOCK_STREAM, 0);
      if (connect(s, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0) {
        std::size_t off = 0;
        while (off < n) {
          const ssize_t w = send(s, frames.data() + off, n - off, MSG_NOSIGNAL);
          if (w <= 0) break;
          off += static_cast<std::size_t>(w);
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(200));
        close(s);
        return true;
      }
      close(s);
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return false;
  };
  ASSERT_TRUE(send_stream(frames.size() / 2));   // dies half way
  std::this_thread::sleep_for(std::chrono::seconds(7));   // longer than the reconnect grace
  ASSERT_TRUE(send_stream(frames.size()));       // a complete scan
  server.join();
  int results = 0;
  for (const auto& e : stdfs::recursive_directory_iterator(out)) results += e.path().filename() == "result.json";
  EXPECT_EQ(results, 2);
}

}  // namespace
