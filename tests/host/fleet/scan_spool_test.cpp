// The gateway's disk spool (host/fleet/scan_spool.hpp): order, bound, restart recovery, interrupted writes,
// rejected scans, names it does not own.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "common/error.hpp"
#include "host/fleet/scan_spool.hpp"
#include "support/error_of.hpp"

namespace {

using namespace fs::host;
using fleet::ScanSpool;
namespace stdfs = std::filesystem;

class SpoolTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = stdfs::temp_directory_path() / ("fs_spool_" + std::to_string(::getpid()) + "_" +
                                           ::testing::UnitTest::GetInstance()->current_test_info()->name());
    stdfs::remove_all(dir_);
  }
  void TearDown() override { stdfs::remove_all(dir_); }
  static std::vector<std::uint8_t> bytes(std::size_t n, std::uint8_t v) {
    return std::vector<std::uint8_t>(n, v);
  }
  stdfs::path dir_;
};

TEST_F(SpoolTest, KeepsOrderAndSurvivesARestart) {
  {
    ScanSpool spool(dir_, 1000);
    EXPECT_EQ(spool.count(), 0u);
    const auto a = spool.put(bytes(100, 1), "cell-1", ScanStatus::Complete);
    const auto b = spool.put(bytes(200, 2), "cell-2", ScanStatus::Disconnected);
    EXPECT_LT(a.sequence, b.sequence);
    EXPECT_EQ(a.path.filename().string(), "000000000001_cell-1_complete.fscan");
    EXPECT_EQ(b.path.filename().string(), "000000000002_cell-2_disconnected.fscan");
    EXPECT_EQ(spool.bytes(), 300u);
    EXPECT_EQ(spool.read(*spool.oldest()), bytes(100, 1));
  }
  // A crash mid-write leaves a .partial file; the next open removes it and takes over the rest in order.
  std::ofstream(dir_ / ".partial-000000000003") << "half a scan";
  std::ofstream(dir_ / "notes.txt") << "not a spooled scan";
  ScanSpool spool(dir_, 1000);
  EXPECT_FALSE(stdfs::exists(dir_ / ".partial-000000000003"));
  EXPECT_TRUE(stdfs::exists(dir_ / "notes.txt"));  // not ours: left alone, not sent
  ASSERT_EQ(spool.count(), 2u);
  auto e = spool.oldest();
  ASSERT_TRUE(e);
  EXPECT_EQ(e->scanner_id, "cell-1");
  EXPECT_EQ(e->status, ScanStatus::Complete);
  spool.remove(*e);
  e = spool.oldest();
  ASSERT_TRUE(e);
  EXPECT_EQ(e->scanner_id, "cell-2");
  EXPECT_EQ(e->status, ScanStatus::Disconnected);
  EXPECT_EQ(spool.read(*e), bytes(200, 2));
  // New scans continue the sequence after what was found.
  EXPECT_EQ(spool.put(bytes(10, 3), "cell-1", ScanStatus::Complete).sequence, 3u);
}

TEST_F(SpoolTest, BoundTakesOneScanWhenEmpty) {
  ScanSpool spool(dir_, 250);
  EXPECT_TRUE(spool.has_room(10'000));  // an empty spool takes any one scan
  spool.put(bytes(200, 1), "cell-1", ScanStatus::Complete);
  EXPECT_TRUE(spool.has_room(50));
  EXPECT_FALSE(spool.has_room(51));
  spool.remove(*spool.oldest());
  EXPECT_TRUE(spool.has_room(251));
}

TEST_F(SpoolTest, RejectedScansAreKeptWithTheirReason) {
  ScanSpool spool(dir_, 1000);
  const auto e = spool.put(bytes(100, 7), "cell-9", ScanStatus::Complete);
  const stdfs::path to = spool.reject(e, "too large for the server");
  EXPECT_EQ(to, dir_ / "rejected" / e.path.filename());
  EXPECT_TRUE(stdfs::exists(to));
  std::ifstream reason(to.string() + ".reason");
  std::string line;
  std::getline(reason, line);
  EXPECT_EQ(line, "too large for the server");
  EXPECT_EQ(spool.count(), 0u);
  EXPECT_EQ(spool.rejected(), 1u);
  EXPECT_EQ(ScanSpool(dir_, 1000).rejected(), 1u);  // counted again after a restart, never resent
  EXPECT_EQ(ScanSpool(dir_, 1000).count(), 0u);
}

TEST_F(SpoolTest, BadDirectoryAndScannerIdAreErrors) {
  std::ofstream(dir_.string() + ".file") << "x";
  const std::string file = dir_.string() + ".file";
  EXPECT_NE(fs::test::error_of([&] { ScanSpool s(file, 1000); }).find("spool " + file + ": cannot create"),
            std::string::npos);
  stdfs::remove(file);
  ScanSpool spool(dir_, 1000);
  EXPECT_NE(
      fs::test::error_of([&] { spool.put(bytes(1, 1), "bad/id", ScanStatus::Complete); }).find("scanner id"),
      std::string::npos);
  EXPECT_EQ(spool.count(), 0u);
}

TEST(SpoolTokens, EveryStatusRoundTrips) {
  for (ScanStatus s :
       {ScanStatus::InProgress, ScanStatus::Complete, ScanStatus::Aborted, ScanStatus::MissingStripes,
        ScanStatus::Disconnected, ScanStatus::Superseded, ScanStatus::ProtocolError, ScanStatus::OverBudget})
    EXPECT_EQ(fleet::parse_status_token(fleet::status_token(s)), s);
  EXPECT_THROW(fleet::parse_status_token("sideways"), fs::Error);
}

TEST_F(SpoolTest, AStreamedScansNonceSurvivesARestart) {
  // A streamed scan whose stream failed is spooled with the nonce of its streamed id (it keeps that id when
  // sent whole); a scanner id with '_' still parses.
  {
    ScanSpool spool(dir_, 1000);
    const auto a = spool.put(bytes(10, 1), "cell_7", ScanStatus::Complete, 0x0123456789abcdefu);
    EXPECT_EQ(a.path.filename().string(), "000000000001_cell_7_complete_s0123456789abcdef.fscan");
    spool.put(bytes(10, 2), "cell_8", ScanStatus::Aborted);
  }
  ScanSpool spool(dir_, 1000);
  ASSERT_EQ(spool.count(), 2u);
  auto e = spool.oldest();
  EXPECT_EQ(e->scanner_id, "cell_7");
  EXPECT_EQ(e->status, ScanStatus::Complete);
  ASSERT_TRUE(e->stream_nonce);
  EXPECT_EQ(*e->stream_nonce, 0x0123456789abcdefu);
  spool.remove(*e);
  e = spool.oldest();
  EXPECT_EQ(e->scanner_id, "cell_8");
  EXPECT_EQ(e->status, ScanStatus::Aborted);
  EXPECT_FALSE(e->stream_nonce);
}

}  // namespace
