#include "common/crc32c.hpp"

#include <array>
#include <atomic>
#include <cstring>

#if defined(FACETSCAN_X86) && (defined(__x86_64__) || defined(_M_X64))
#include <nmmintrin.h>
#define FS_CRC_HW 1
#endif

namespace fs {
namespace {

constexpr std::uint32_t kPoly = 0x82F63B78u;

struct Tables {
  std::uint32_t t[8][256];
};

constexpr Tables make_tables() {
  Tables tb{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1) ? (c >> 1) ^ kPoly : c >> 1;
    tb.t[0][i] = c;
  }
  for (std::uint32_t i = 0; i < 256; ++i)
    for (int s = 1; s < 8; ++s) tb.t[s][i] = (tb.t[s - 1][i] >> 8) ^ tb.t[0][tb.t[s - 1][i] & 0xFF];
  return tb;
}

constexpr Tables kTables = make_tables();

std::uint64_t load_u64_le(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

#ifdef FS_CRC_HW
__attribute__((target("sse4.2"))) std::uint32_t crc_sse42(const std::uint8_t* p, std::size_t n,
                                                          std::uint32_t c) {
  std::uint64_t c64 = c;
  while (n > 0 && (reinterpret_cast<std::uintptr_t>(p) & 7) != 0) {
    c64 = _mm_crc32_u8(static_cast<std::uint32_t>(c64), *p++);
    --n;
  }
  while (n >= 32) {
    std::uint64_t a, b, d, e;
    std::memcpy(&a, p, 8);
    std::memcpy(&b, p + 8, 8);
    std::memcpy(&d, p + 16, 8);
    std::memcpy(&e, p + 24, 8);
    c64 = _mm_crc32_u64(c64, a);
    c64 = _mm_crc32_u64(c64, b);
    c64 = _mm_crc32_u64(c64, d);
    c64 = _mm_crc32_u64(c64, e);
    p += 32;
    n -= 32;
  }
  while (n >= 8) {
    std::uint64_t a;
    std::memcpy(&a, p, 8);
    c64 = _mm_crc32_u64(c64, a);
    p += 8;
    n -= 8;
  }
  std::uint32_t c32 = static_cast<std::uint32_t>(c64);
  while (n-- > 0) c32 = _mm_crc32_u8(c32, *p++);
  return c32;
}

bool detect_hw() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("sse4.2");
}
#endif

}  // namespace

std::uint32_t crc32c_table(std::span<const std::uint8_t> data, std::uint32_t crc) {
  const auto& t = kTables.t;
  std::uint32_t c = ~crc;
  const std::uint8_t* p = data.data();
  std::size_t n = data.size();
  while (n >= 8) {
    const std::uint64_t v = load_u64_le(p) ^ c;
    c = t[7][v & 0xFF] ^ t[6][(v >> 8) & 0xFF] ^ t[5][(v >> 16) & 0xFF] ^ t[4][(v >> 24) & 0xFF] ^
        t[3][(v >> 32) & 0xFF] ^ t[2][(v >> 40) & 0xFF] ^ t[1][(v >> 48) & 0xFF] ^ t[0][v >> 56];
    p += 8;
    n -= 8;
  }
  while (n-- > 0) c = (c >> 8) ^ t[0][(c ^ *p++) & 0xFF];
  return ~c;
}

bool crc32c_hw_available() {
#ifdef FS_CRC_HW
  static const bool ok = detect_hw();
  return ok;
#else
  return false;
#endif
}

std::uint32_t crc32c_hw(std::span<const std::uint8_t> data, std::uint32_t crc) {
#ifdef FS_CRC_HW
  if (crc32c_hw_available()) return ~crc_sse42(data.data(), data.size(), ~crc);
#endif
  return crc32c_table(data, crc);
}

namespace {
std::atomic<bool> g_use_hw{crc32c_hw_available()};
}

void crc32c_use_hw(bool enable) {
  g_use_hw.store(enable && crc32c_hw_available(), std::memory_order_relaxed);
}
bool crc32c_using_hw() { return g_use_hw.load(std::memory_order_relaxed); }

std::uint32_t crc32c(std::span<const std::uint8_t> data, std::uint32_t crc) {
#ifdef FS_CRC_HW
  if (g_use_hw.load(std::memory_order_relaxed)) return ~crc_sse42(data.data(), data.size(), ~crc);
#endif
  return crc32c_table(data, crc);
}

}  // namespace fs
