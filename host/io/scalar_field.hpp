#pragma once
// One typed scalar in a binary record (PCD TYPE/SIZE or PLY property type), read with memcpy.
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>

namespace fs::host::io_detail {

enum class ScalarKind : std::uint8_t { Int, UInt, Float };

struct ScalarType {
  ScalarKind kind = ScalarKind::Float;
  std::uint8_t size = 4;  // 1, 2, 4 or 8 bytes
};

template <typename T>
inline T load_as(const std::byte* p, bool swap) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  if (swap && sizeof(T) > 1) {
    unsigned char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) {
      const unsigned char t = b[i];
      b[i] = b[sizeof(T) - 1 - i];
      b[sizeof(T) - 1 - i] = t;
    }
    std::memcpy(&v, b, sizeof(T));
  }
  return v;
}

// Reads the scalar at p as double; swap = the data's byte order differs from the host's.
inline double load_scalar(const std::byte* p, ScalarType t, bool swap = false) {
  switch (t.kind) {
    case ScalarKind::Float:
      return t.size == 8 ? load_as<double>(p, swap) : static_cast<double>(load_as<float>(p, swap));
    case ScalarKind::Int:
      switch (t.size) {
        case 1:
          return load_as<std::int8_t>(p, swap);
        case 2:
          return load_as<std::int16_t>(p, swap);
        case 4:
          return load_as<std::int32_t>(p, swap);
        default:
          return static_cast<double>(load_as<std::int64_t>(p, swap));
      }
    case ScalarKind::UInt:
      switch (t.size) {
        case 1:
          return load_as<std::uint8_t>(p, swap);
        case 2:
          return load_as<std::uint16_t>(p, swap);
        case 4:
          return load_as<std::uint32_t>(p, swap);
        default:
          return static_cast<double>(load_as<std::uint64_t>(p, swap));
      }
  }
  return 0.0;
}

// Integer scalars read exactly (labels); floats are truncated.
inline std::int64_t load_integer(const std::byte* p, ScalarType t, bool swap = false) {
  if (t.kind == ScalarKind::UInt && t.size == 8)
    return static_cast<std::int64_t>(load_as<std::uint64_t>(p, swap));
  if (t.kind == ScalarKind::Int && t.size == 8) return load_as<std::int64_t>(p, swap);
  const double v = load_scalar(p, t, swap);
  if (!(v == v) || v > 9.2e18 || v < -9.2e18) return 0;
  return static_cast<std::int64_t>(v);
}

}  // namespace fs::host::io_detail
