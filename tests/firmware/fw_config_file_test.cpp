// facetscan-fw --config FILE: the file reader refuses devices, links to them and files above the cap (the
// JSON itself is fuzz_fw_config's), naming the path.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "common/error.hpp"
#include "common/input_file.hpp"
#include "firmware/fw_config.hpp"
#include "support/error_of.hpp"

namespace {

using fs::test::error_of;
namespace stdfs = std::filesystem;

TEST(FwConfigFile, DevicesLinksAndOversizedFilesAreRefused) {
  fs::fw::FwConfig cfg;
  EXPECT_EQ(error_of([&] { fs::fw::load_config_file(cfg, "/dev/zero"); }),
            "/dev/zero: not a regular file (character device)");
  const auto dir = stdfs::temp_directory_path() / ("fs_fw_config_" + std::to_string(::getpid()));
  stdfs::remove_all(dir);
  stdfs::create_directories(dir);
  stdfs::create_symlink("/dev/zero", dir / "board.json");
  EXPECT_EQ(error_of([&] { fs::fw::load_config_file(cfg, (dir / "board.json").string()); }),
            (dir / "board.json").string() + ": not a regular file (character device)");
  const auto big = dir / "big.json";
  const int fd = ::open(big.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::ftruncate(fd, static_cast<off_t>(fs::kMaxConfigFileBytes + 1)), 0);
  ::close(fd);
  EXPECT_EQ(error_of([&] { fs::fw::load_config_file(cfg, big.string()); }),
            big.string() + ": 1.0 MB, more than the 1 MiB a firmware configuration may have");
  // A real file still loads.
  std::ofstream(dir / "ok.json") << R"({"steps": 7})";
  EXPECT_EQ(error_of([&] { fs::fw::load_config_file(cfg, (dir / "ok.json").string()); }), "<no error>");
  EXPECT_EQ(cfg.loop.steps, 7u);
  stdfs::remove_all(dir);
}

TEST(FwConfigFile, ScanIdIsTakenAndChecked) {
  fs::fw::FwConfig cfg;
  EXPECT_EQ(cfg.loop.scan_id, 1u);
  fs::fw::apply_config_json(cfg, R"({"scan_id": 42})", "board.json");
  EXPECT_EQ(cfg.loop.scan_id, 42u);
  EXPECT_EQ(error_of([&] {
              fs::fw::apply_config_json(cfg, R"({"scan_id": 0})", "board.json");
            }).rfind("board.json: scan_id: out of range", 0),
            0u);
  EXPECT_EQ(error_of([&] { fs::fw::apply_config_json(cfg, R"({"scan_id": 2.5})", "board.json"); }),
            "board.json: scan_id: expected an integer");
}

TEST(FwConfigFile, CpuLatencyLimitIsTakenAndChecked) {
  fs::fw::FwConfig cfg;
  EXPECT_EQ(cfg.rt_cpu_latency_us, 0);
  fs::fw::apply_config_json(cfg, R"({"rt": true, "rt_cpu_latency_us": 25})", "board.json");
  EXPECT_EQ(cfg.rt_cpu_latency_us, 25);
  fs::fw::apply_config_json(cfg, R"({"rt_cpu_latency_us": -1})", "board.json");
  EXPECT_EQ(cfg.rt_cpu_latency_us, -1);
  EXPECT_EQ(error_of([&] {
              fs::fw::apply_config_json(cfg, R"({"rt_cpu_latency_us": -2})", "board.json");
            }).rfind("board.json: rt_cpu_latency_us: out of range", 0),
            0u);
}

TEST(FwConfigFile, StreamDrainIsTakenAndChecked) {
  fs::fw::FwConfig cfg;
  EXPECT_EQ(cfg.stream_drain_ms, 2000u);
  fs::fw::apply_config_json(cfg, R"({"stream_drain_ms": 30000})", "board.json");
  EXPECT_EQ(cfg.stream_drain_ms, 30000u);
  EXPECT_EQ(error_of([&] {
              fs::fw::apply_config_json(cfg, R"({"stream_drain_ms": -1})", "board.json");
            }).rfind("board.json: stream_drain_ms: out of range", 0),
            0u);
}

}  // namespace
