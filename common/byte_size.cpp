#include "common/byte_size.hpp"

#include <cctype>
#include <cmath>
#include <cstdio>

#include "common/error.hpp"

namespace fs {

std::uint64_t parse_byte_size(const std::string& text) {
  auto fail = [&](const char* why) {
    return Error(
        "byte size '" + text + "': " + why +
        " (expected a number of bytes with an optional unit K, M, G or T, powers of 1024: e.g. 512M, 2G)");
  };
  std::size_t i = 0;
  const std::size_t n = text.size();
  std::uint64_t whole = 0;
  std::size_t digits = 0;
  for (; i < n && std::isdigit(static_cast<unsigned char>(text[i])); ++i, ++digits) {
    const std::uint64_t d = static_cast<std::uint64_t>(text[i] - '0');
    if (whole > (UINT64_MAX - d) / 10) throw fail("too large");
    whole = whole * 10 + d;
  }
  double fraction = 0.0;
  bool has_fraction = false;
  if (i < n && text[i] == '.') {
    has_fraction = true;
    double scale = 0.1;
    for (++i; i < n && std::isdigit(static_cast<unsigned char>(text[i])); ++i, ++digits, scale /= 10)
      fraction += scale * (text[i] - '0');
  }
  if (digits == 0) throw fail("no number");
  std::uint64_t unit = 1;
  if (i < n) {
    switch (std::toupper(static_cast<unsigned char>(text[i]))) {
      case 'K':
        unit = std::uint64_t(1) << 10;
        break;
      case 'M':
        unit = std::uint64_t(1) << 20;
        break;
      case 'G':
        unit = std::uint64_t(1) << 30;
        break;
      case 'T':
        unit = std::uint64_t(1) << 40;
        break;
      case 'B':
        break;
      default:
        throw fail("unknown unit");
    }
    const bool bytes_only = std::toupper(static_cast<unsigned char>(text[i])) == 'B';
    ++i;
    if (!bytes_only) {
      if (i < n && (text[i] == 'i' || text[i] == 'I')) ++i;
      if (i < n && (text[i] == 'b' || text[i] == 'B')) ++i;
    }
    if (i != n) throw fail("unknown unit");
  }
  if (has_fraction && unit == 1) throw fail("a fraction of a byte");
  if (whole > UINT64_MAX / unit) throw fail("too large");
  const std::uint64_t base = whole * unit;
  const auto extra = static_cast<std::uint64_t>(std::floor(fraction * double(unit)));
  if (base > UINT64_MAX - extra) throw fail("too large");
  return base + extra;
}

std::string format_byte_size(std::uint64_t bytes) {
  static const char* const kUnits[] = {"KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
  if (bytes < 1024) return std::to_string(bytes) + " B";
  double v = double(bytes) / 1024.0;
  int u = 0;
  while (v >= 1024.0 && u < 5) {
    v /= 1024.0;
    ++u;
  }
  char buf[32];
  if (v < 10.0 && std::abs(v - std::round(v)) >= 0.05)
    std::snprintf(buf, sizeof buf, "%.1f %s", v, kUnits[u]);
  else
    std::snprintf(buf, sizeof buf, "%.0f %s", v, kUnits[u]);
  return buf;
}

}  // namespace fs
