// common/byte_buffer.hpp: growth keeps the bytes, large buffers sit in a mapping of their own (no heap
// allocation), moves hand the bytes over; read_input_bytes() of a large file and of a file that grows while
// it is read.
#include "common/byte_buffer.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <numeric>
#include <vector>

#include "common/alloc_counter/alloc_counter.hpp"
#include "common/input_file.hpp"
#include "support/error_of.hpp"
#include "tmp_dir.hpp"

namespace {

using namespace fs;
using ::testing::HasSubstr;

void fill_pattern(ByteBuffer& b, std::size_t from) {
  for (std::size_t i = from; i < b.size(); ++i) b[i] = static_cast<std::byte>((i * 131 + 7) & 0xff);
}

bool has_pattern(const ByteBuffer& b, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i)
    if (b[i] != static_cast<std::byte>((i * 131 + 7) & 0xff)) return false;
  return true;
}

TEST(ByteBuffer, GrowingKeepsTheBytesFromSmallToMapped) {
  ByteBuffer b(1000);
  EXPECT_FALSE(b.mapped());
  fill_pattern(b, 0);
  b.resize(1001);  // grows by 1.5x: room for more without another copy
  EXPECT_GE(b.capacity(), 1500u);
  const std::byte* before = b.data();
  b.resize(1400);
  EXPECT_EQ(b.data(), before);
  EXPECT_TRUE(has_pattern(b, 1000));
  fill_pattern(b, 1000);
  b.resize(ByteBuffer::kHugeBufferBytes + 5);  // into a mapping of whole huge pages
  EXPECT_TRUE(b.mapped());
  EXPECT_EQ(b.capacity() % ByteBuffer::kHugeBufferBytes, 0u);
  EXPECT_GE(b.capacity(), ByteBuffer::kHugeBufferBytes + 5);
  EXPECT_TRUE(has_pattern(b, 1400));
  fill_pattern(b, 1400);
  b.resize(10);  // shrinking keeps the storage
  EXPECT_TRUE(b.mapped());
  EXPECT_EQ(b.size(), 10u);
  EXPECT_EQ(b.span().size(), 10u);
  EXPECT_TRUE(has_pattern(b, 10));
}

TEST(ByteBuffer, ALargeBufferTakesNothingFromTheHeap) {
  AllocCounter c;
  ByteBuffer b(3 * ByteBuffer::kHugeBufferBytes);
  EXPECT_TRUE(b.mapped());
  EXPECT_EQ(c.allocations(), 0u);
  ByteBuffer small(100);
  EXPECT_FALSE(small.mapped());
  EXPECT_EQ(c.allocations(), 1u);
}

TEST(ByteBuffer, MovesHandTheBytesOver) {
  ByteBuffer a(ByteBuffer::kHugeBufferBytes);
  fill_pattern(a, 0);
  const std::byte* p = a.data();
  ByteBuffer b(std::move(a));
  EXPECT_EQ(b.data(), p);
  EXPECT_EQ(a.data(), nullptr);  // NOLINT(bugprone-use-after-move): moved-from is empty by contract
  EXPECT_EQ(a.size(), 0u);
  ByteBuffer c(10);
  c = std::move(b);
  EXPECT_EQ(c.data(), p);
  EXPECT_TRUE(c.mapped());
  EXPECT_TRUE(has_pattern(c, c.size()));
}

TEST(ByteBuffer, ALargeFileIsReadWholeIntoMappedBytes) {
  const auto dir = test::make_tmp_dir("bytebuffer");
  std::vector<unsigned char> content(5 * 1000 * 1000 + 17);
  for (std::size_t i = 0; i < content.size(); ++i)
    content[i] = static_cast<unsigned char>((i * 131 + 7) & 0xff);
  {
    std::ofstream f(dir / "big.bin", std::ios::binary);
    f.write(reinterpret_cast<const char*>(content.data()), static_cast<std::streamsize>(content.size()));
  }
  const ByteBuffer bytes = read_input_bytes(dir / "big.bin", kMaxLibraryFileBytes, "model library");
  ASSERT_EQ(bytes.size(), content.size());
  EXPECT_TRUE(bytes.mapped());
  EXPECT_TRUE(has_pattern(bytes, bytes.size()));
}

// A /proc file is a regular file whose fstat() size is 0: every byte arrives after the size was taken,
// through the path that reads a file that grew while being read.
TEST(ByteBuffer, AFileThatGrowsWhileReadIsReadWholeOrRefusedAtTheCap) {
  const ByteBuffer status = read_input_bytes("/proc/self/status", kMaxConfigFileBytes, "test file");
  ASSERT_GT(status.size(), 100u);
  const std::string text(reinterpret_cast<const char*>(status.data()), status.size());
  EXPECT_EQ(text.rfind("Name:", 0), 0u);
  EXPECT_THAT(text, HasSubstr("\nPid:"));
  EXPECT_EQ(test::error_of([] { read_input_bytes("/proc/self/status", 64, "test file"); }),
            "/proc/self/status: grew beyond the 64 bytes a test file may have while being read");
}

}  // namespace
