// common/input_file.hpp: devices, FIFOs, directories and links to them are refused; files above a reader's
// cap are refused without reading them; declared counts are checked against the bytes in the file. The same
// rules through the readers of common/: meshes and .fscan files.
#include "common/input_file.hpp"

#include <fcntl.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fstream>

#include "common/alloc_counter/alloc_counter.hpp"
#include "common/mesh_io.hpp"
#include "common/scan_file.hpp"
#include "support/error_of.hpp"
#include "tmp_dir.hpp"

namespace {

using namespace fs;
using test::error_of;
using ::testing::HasSubstr;

// A file of `size` bytes that takes no disk space (a hole).
void make_sparse(const std::filesystem::path& p, std::uint64_t size) {
  const int fd = ::open(p.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::ftruncate(fd, static_cast<off_t>(size)), 0);
  ::close(fd);
}

void write_text(const std::filesystem::path& p, const std::string& s) {
  std::ofstream(p, std::ios::binary) << s;
}

TEST(InputFile, ReadsARegularFileWhole) {
  const auto dir = test::make_tmp_dir("input");
  write_text(dir / "a.json", "{\"x\": 1}\n");
  EXPECT_EQ(read_input_file(dir / "a.json", 100, "test file"), "{\"x\": 1}\n");
  write_text(dir / "empty.json", "");
  EXPECT_EQ(read_input_file(dir / "empty.json", 100, "test file"), "");
  const auto bytes = read_input_bytes(dir / "a.json", 9, "test file");  // exactly at the cap
  EXPECT_EQ(bytes.size(), 9u);
  EXPECT_EQ(static_cast<char>(bytes[0]), '{');
}

TEST(InputFile, RefusesDevicesAndLinksToThem) {
  EXPECT_EQ(error_of([] { read_input_file("/dev/zero", kMaxConfigFileBytes, "test file"); }),
            "/dev/zero: not a regular file (character device)");
  const auto dir = test::make_tmp_dir("input");
  std::filesystem::create_symlink("/dev/zero", dir / "zero.json");
  EXPECT_EQ(error_of([&] { read_input_bytes(dir / "zero.json", kMaxCloudFileBytes, "test file"); }),
            (dir / "zero.json").string() + ": not a regular file (character device)");
  EXPECT_EQ(error_of([&] { read_input_file(dir, kMaxConfigFileBytes, "test file"); }),
            dir.string() + ": not a regular file (directory)");
}

TEST(InputFile, RefusesAFifoWithoutWaitingForAWriter) {
  const auto dir = test::make_tmp_dir("input");
  ASSERT_EQ(::mkfifo((dir / "pipe.json").c_str(), 0600), 0);
  EXPECT_EQ(error_of([&] { read_input_file(dir / "pipe.json", kMaxConfigFileBytes, "test file"); }),
            (dir / "pipe.json").string() + ": not a regular file (FIFO)");
}

TEST(InputFile, MissingFileNamesThePathAndTheKind) {
  EXPECT_EQ(error_of([] { read_input_file("/nonexistent/cfg.json", 100, "firmware configuration"); }),
            "/nonexistent/cfg.json: cannot open firmware configuration: No such file or directory");
}

TEST(InputFile, FileAboveTheCapIsRefusedBeforeItIsRead) {
  const auto dir = test::make_tmp_dir("input");
  make_sparse(dir / "big.json", kMaxConfigFileBytes + 1);
  AllocCounter c;
  EXPECT_EQ(
      error_of([&] { read_input_file(dir / "big.json", kMaxConfigFileBytes, "firmware configuration"); }),
      (dir / "big.json").string() + ": 1.0 MB, more than the 1 MiB a firmware configuration may have");
  // Nothing of the size of the file was allocated (the message and the path only).
  if (AllocCounter::counts_malloc()) {
    EXPECT_LT(c.bytes(), 64 * kKiB);
  }
  make_sparse(dir / "cloud.pcd", kMaxCloudFileBytes + 1);
  EXPECT_EQ(error_of([&] { read_input_bytes(dir / "cloud.pcd", kMaxCloudFileBytes, "point-cloud file"); }),
            (dir / "cloud.pcd").string() + ": 4.3 GB, more than the 4 GiB a point-cloud file may have");
}

TEST(InputFile, DeclaredCountsAreCheckedAgainstTheBytesLeft) {
  EXPECT_EQ(error_of([] { check_declared("x.pcd", "POINTS", 100000000, 16, 150); }),
            "x.pcd: POINTS 100000000 x 16 bytes = 1.6 GB but the file has 150 bytes after the header");
  EXPECT_EQ(error_of([] { check_declared("x.pcd", "POINTS", 10, 16, 160); }), "<no error>");  // exactly fits
  EXPECT_EQ(error_of([] { check_declared("x.pcd", "POINTS", 11, 16, 160); }),
            "x.pcd: POINTS 11 x 16 bytes = 176 bytes but the file has 160 bytes after the header");
  // No overflow in declared x size.
  EXPECT_EQ(
      error_of([] { check_declared("a.ply", "element 'v'", UINT64_MAX, 1u << 20, 5, "after it"); }),
      "a.ply: element 'v' 18446744073709551615 x 1048576 bytes = more than 2^64 bytes but the file has 5 "
      "bytes after it");
  EXPECT_EQ(error_of([] { check_declared("a.ply", "element 'v'", 0, 4, 0); }), "<no error>");
}

TEST(InputFile, SizesInMessages) {
  EXPECT_EQ(format_bytes(150), "150 bytes");
  EXPECT_EQ(format_bytes(1600000000), "1.6 GB");
  EXPECT_EQ(format_bytes(773000000), "773.0 MB");
  EXPECT_EQ(format_cap(kMiB), "1 MiB");
  EXPECT_EQ(format_cap(4 * kGiB), "4 GiB");
  EXPECT_EQ(format_cap(1500000), "1.5 MB");
}

TEST(InputFile, MeshReaderRefusesDevicesAndHugeFiles) {
  const auto dir = test::make_tmp_dir("input");
  std::filesystem::create_symlink("/dev/zero", dir / "zero.off");
  EXPECT_EQ(error_of([&] { read_mesh(dir / "zero.off"); }),
            (dir / "zero.off").string() + ": not a regular file (character device)");
  make_sparse(dir / "huge.stl", kMaxMeshFileBytes + 1);
  EXPECT_THAT(error_of([&] { read_mesh(dir / "huge.stl"); }),
              HasSubstr("huge.stl: 1.1 GB, more than the 1 GiB a mesh file may have"));
}

TEST(InputFile, ScanFileReaderRefusesDevices) {
  const auto dir = test::make_tmp_dir("input");
  std::filesystem::create_symlink("/dev/zero", dir / "zero.fscan");
  EXPECT_EQ(error_of([&] { ScanFileReader r(dir / "zero.fscan"); }),
            (dir / "zero.fscan").string() + ": not a regular file (character device)");
  EXPECT_EQ(error_of([] { ScanFileReader r(std::filesystem::path("/dev/null")); }),
            "/dev/null: not a regular file (character device)");
}

}  // namespace
