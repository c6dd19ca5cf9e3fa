#include "common/crc32c.hpp"

#include <gtest/gtest.h>

#include <random>
#include <string_view>
#include <vector>

namespace {

std::span<const std::uint8_t> bytes(std::string_view s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

TEST(Crc32c, KnownVectors) {
  // RFC 3720 (iSCSI) B.4 and the common check value.
  EXPECT_EQ(fs::crc32c(bytes("123456789")), 0xE3069283u);
  EXPECT_EQ(fs::crc32c_table(bytes("123456789")), 0xE3069283u);
  std::vector<std::uint8_t> zeros(32, 0), ones(32, 0xFF), inc(32);
  for (int i = 0; i < 32; ++i) inc[i] = static_cast<std::uint8_t>(i);
  EXPECT_EQ(fs::crc32c(zeros), 0x8A9136AAu);
  EXPECT_EQ(fs::crc32c(ones), 0x62A8AB43u);
  EXPECT_EQ(fs::crc32c(inc), 0x46DD794Eu);
  EXPECT_EQ(fs::crc32c(std::span<const std::uint8_t>{}), 0u);
}

TEST(Crc32c, HardwareAndTableAgreeOnAllLengthsAndAlignments) {
  std::mt19937 rng(7);
  std::vector<std::uint8_t> buf(4096 + 16);
  for (auto& b : buf) b = static_cast<std::uint8_t>(rng());
  for (std::size_t off = 0; off < 9; ++off)
    for (std::size_t len : {0u, 1u, 3u, 7u, 8u, 9u, 31u, 32u, 33u, 63u, 100u, 1000u, 4096u}) {
      std::span<const std::uint8_t> s(buf.data() + off, len);
      ASSERT_EQ(fs::crc32c_hw(s), fs::crc32c_table(s)) << "off " << off << " len " << len;
      ASSERT_EQ(fs::crc32c(s), fs::crc32c_table(s));
    }
}

TEST(Crc32c, Incremental) {
  const std::string_view s = "The quick brown fox jumps over the lazy dog";
  for (std::size_t cut = 0; cut <= s.size(); ++cut) {
    const auto a = bytes(s.substr(0, cut)), b = bytes(s.substr(cut));
    EXPECT_EQ(fs::crc32c(b, fs::crc32c(a)), fs::crc32c(bytes(s)));
    EXPECT_EQ(fs::crc32c_table(b, fs::crc32c_table(a)), fs::crc32c(bytes(s)));
  }
}

TEST(Crc32c, DetectsSingleBitFlips) {
  std::vector<std::uint8_t> buf(256);
  for (std::size_t i = 0; i < buf.size(); ++i) buf[i] = static_cast<std::uint8_t>(i * 31);
  const auto ref = fs::crc32c(buf);
  for (std::size_t bit = 0; bit < buf.size() * 8; bit += 13) {
    buf[bit / 8] ^= static_cast<std::uint8_t>(1u << (bit % 8));
    EXPECT_NE(fs::crc32c(buf), ref);
    buf[bit / 8] ^= static_cast<std::uint8_t>(1u << (bit % 8));
  }
}

}  // namespace

namespace {
TEST(Crc32c, ForcingTheTableGivesTheSameResults) {
  std::vector<std::uint8_t> buf(1000);
  for (std::size_t i = 0; i < buf.size(); ++i) buf[i] = static_cast<std::uint8_t>(i * 13 + 5);
  const auto ref = fs::crc32c(buf);
  fs::crc32c_use_hw(false);
  EXPECT_FALSE(fs::crc32c_using_hw());
  EXPECT_EQ(fs::crc32c(buf), ref);
  fs::crc32c_use_hw(true);
  EXPECT_EQ(fs::crc32c_using_hw(), fs::crc32c_hw_available());
  EXPECT_EQ(fs::crc32c(buf), ref);
}
}  // namespace
