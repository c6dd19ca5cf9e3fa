#pragma once
// Byte counts on the command line and in messages (`--memory-budget 2G`).
#include <cstdint>
#include <string>

namespace fs {

// Parses "2147483648", "512M", "2G", "1.5G", "64k", "512MiB", "2GB": a number (decimals allowed with a
// unit) and an optional unit K, M, G or T (case-insensitive, powers of 1024; a trailing "B" or "iB" is
// accepted). Throws fs::Error naming the text for anything else (empty, negative, unknown unit, above
// 2^64 - 1 bytes).
std::uint64_t parse_byte_size(const std::string& text);

// "512 B", "16 KiB", "1.5 GiB", "150 GiB" (one decimal below 10 units when not whole).
std::string format_byte_size(std::uint64_t bytes);

}  // namespace fs
