#pragma once
// CRC-32C (Castagnoli, reflected polynomial 0x82F63B78, init/xorout 0xFFFFFFFF; crc32c("123456789") =
// 0xE3069283). crc32c() uses the SSE4.2 crc32 instruction when the CPU has it (runtime check) and a
// slicing-by-8 table otherwise. Incremental: crc32c(b, crc32c(a)) == crc32c(a ++ b).
#include <cstddef>
#include <cstdint>
#include <span>

namespace fs {

std::uint32_t crc32c(std::span<const std::uint8_t> data, std::uint32_t crc = 0);

// The two implementations, exposed for tests and benchmarks.
std::uint32_t crc32c_table(std::span<const std::uint8_t> data, std::uint32_t crc = 0);
// Only valid when crc32c_hw_available(); otherwise falls back to the table.
std::uint32_t crc32c_hw(std::span<const std::uint8_t> data, std::uint32_t crc = 0);
bool crc32c_hw_available();
// Lets crc32c() use the instruction (default: when available) or force the table (benchmarks, tests).
void crc32c_use_hw(bool enable);
bool crc32c_using_hw();

}  // namespace fs
