// The host's file readers do not trust a file: devices and links to them are refused, files above the
// reader's cap are refused unread, and a header's counts are checked against the bytes that follow it before
// anything is allocated for them (PCD ascii / binary / binary_compressed, PLY; calibration JSON, .fscan).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "common/alloc_counter/alloc_counter.hpp"
#include "common/error.hpp"
#include "common/input_file.hpp"
#include "host/io/calibration_json.hpp"
#include "host/io/cloud_readers.hpp"
#include "host/io/load.hpp"
#include "support/error_of.hpp"

namespace fs::host {
namespace {

using test::error_of;
namespace stdfs = std::filesystem;

stdfs::path tmp_dir(const std::string& tag) {
  const auto d = stdfs::temp_directory_path() / ("fs_io_limits_" + tag + "_" + std::to_string(::getpid()));
  stdfs::remove_all(d);
  stdfs::create_directories(d);
  return d;
}

std::span<const std::byte> bytes_of(const std::string& s) {
  return {reinterpret_cast<const std::byte*>(s.data()), s.size()};
}

// Parses `text` as `fmt` ("pcd" / "ply"), returns the error message and the bytes allocated meanwhile.
std::string read_error(const std::string& text, const std::string& fmt, std::uint64_t& allocated) {
  OrganizedCloud out;
  AllocCounter c;
  const std::string e = error_of([&] {
    if (fmt == "pcd")
      read_pcd(bytes_of(text), "tiny." + fmt, out);
    else
      read_ply(bytes_of(text), "tiny." + fmt, out);
  });
  allocated = c.bytes();
  return e;
}

TEST(InputLimits, CloudFileThatIsALinkToADeviceIsRefused) {
  const auto dir = tmp_dir("dev");
  for (const char* name : {"zero.pcd", "zero.ply", "zero.fscan"}) {
    stdfs::create_symlink("/dev/zero", dir / name);
    OrganizedCloud out;
    EXPECT_EQ(error_of([&] { load_cloud((dir / name).string(), out); }),
              (dir / name).string() + ": not a regular file (character device)");
  }
  EXPECT_EQ(error_of([] { read_calibration_file("/dev/zero"); }),
            "/dev/zero: not a regular file (character device)");
  stdfs::remove_all(dir);
}

TEST(InputLimits, CloudAndCalibrationFilesAboveTheCapAreRefused) {
  const auto dir = tmp_dir("cap");
  const auto sparse = [&](const char* name, std::uint64_t size) {
    const auto p = dir / name;
    const int fd = ::open(p.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    EXPECT_GE(fd, 0);
    EXPECT_EQ(::ftruncate(fd, static_cast<off_t>(size)), 0);
    ::close(fd);
    return p.string();
  };
  OrganizedCloud out;
  const auto pcd = sparse("big.pcd", kMaxCloudFileBytes + 1);
  AllocCounter c;
  EXPECT_EQ(error_of([&] { load_cloud(pcd, out); }),
            pcd + ": 4.3 GB, more than the 4 GiB a point-cloud file may have");
  if (AllocCounter::counts_malloc()) {
    EXPECT_LT(c.bytes(), 64 * kKiB);
  }
  const auto cal = sparse("cal.json", kMaxConfigFileBytes + 1);
  EXPECT_EQ(error_of([&] { read_calibration_file(cal); }),
            cal + ": 1.0 MB, more than the 1 MiB a calibration file may have");
  stdfs::remove_all(dir);
}

// A ~100-byte header that declares 64 M ascii points: refused before the 64 M-cell cloud is allocated.
TEST(InputLimits, PcdAsciiCountBeyondTheFileIsRefusedBeforeAllocating) {
  const std::string head =
      "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 8000\nHEIGHT 8000\nPOINTS 64000000\nDATA "
      "ascii\n";
  std::uint64_t allocated = 0;
  EXPECT_EQ(
      read_error(head + "1 2 3\n", "pcd", allocated),
      "tiny.pcd: POINTS 64000000 x 6 bytes = 384.0 MB but the file has 6 bytes after the header (ascii: at "
      "least 2 bytes a value)");
  if (AllocCounter::counts_malloc()) {
    EXPECT_LT(allocated, 1024 * 1024u);
  }
  // The bound is exact: 2 points of 3 one-digit values fit in "1 2 3\n4 5 6" (11 bytes, no final newline).
  OrganizedCloud out;
  const std::string two =
      "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n1 2 3\n4 "
      "5 6";
  EXPECT_EQ(error_of([&] { read_pcd(bytes_of(two), "two.pcd", out); }), "<no error>");
  EXPECT_EQ(out.points.size(), 2u);
}

TEST(InputLimits, PcdCompressedSizeBeyondWhatLzfCanExpandIsRefused) {
  // 1 M points of 16 bytes = 16 MB "uncompressed" from 10 compressed bytes.
  std::string s =
      "FIELDS x y z w\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 1000000\nHEIGHT 1\nDATA "
      "binary_compressed\n";
  const std::uint32_t csize = 10, usize = 16000000;
  s.append(reinterpret_cast<const char*>(&csize), 4);
  s.append(reinterpret_cast<const char*>(&usize), 4);
  s.append(10, '\0');
  std::uint64_t allocated = 0;
  const std::string e = read_error(s, "pcd", allocated);
  EXPECT_NE(e.find("tiny.pcd: at byte"), std::string::npos) << e;
  EXPECT_NE(
      e.find("uncompressed size 16000000 (16.0 MB) cannot come from 10 compressed bytes (LZF expands at "
             "most 88x)"),
      std::string::npos)
      << e;
  if (AllocCounter::counts_malloc()) {
    EXPECT_LT(allocated, 1024 * 1024u);
  }
}

TEST(InputLimits, PlyCountsBeyondTheFileAreRefusedBeforeAllocating) {
  // A binary vertex element of 12-byte instances: 100 declared in a file that holds 2.
  const std::string head =
      "ply\nformat binary_little_endian 1.0\nelement vertex 100\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n";
  std::uint64_t allocated = 0;
  EXPECT_EQ(
      read_error(head + std::string(24, '\0'), "ply", allocated),
      "tiny.ply: element 'vertex' 100 x 12 bytes = 1200 bytes but the file has 24 bytes after the header");
  // Ascii: 2 bytes a value, and a second element counts what the first one left.
  const std::string asc =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
      "element range_grid 40\nproperty list uchar int vertex_indices\nend_header\n1 2 3\n1 0\n";
  EXPECT_EQ(
      read_error(asc, "ply", allocated),
      "tiny.ply: element 'range_grid' 40 x 2 bytes = 80 bytes but the file has 4 bytes after the header and "
      "the elements before it (ascii: at least 2 bytes a value)");
  if (AllocCounter::counts_malloc()) {
    EXPECT_LT(allocated, 64 * 1024u);
  }
}

}  // namespace
}  // namespace fs::host
