#pragma once
// A library of reference models and its versioned binary file (.fslib).
//
// .fslib layout (little-endian): "FSLIB\r\n\x1a" (8 bytes), u32 version (1), u32 model count, u64 payload
// size, u32 CRC-32 of the payload, then the payload: per model: string name, u8 open, u32 face count, per
// face (normal 3 f64, offset f64, area f64, centroid 3 f64, u32 loop count, per loop u32 vertex count + 3 f64
// each), u32 arc count, per arc (u32 a, u32 b, f64 border), u32 symmetry count, 9 f64 each (row major).
// Strings are u32 length + bytes. Totals, centre and radius are recomputed on load.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "host/library/model.hpp"

namespace fs::host {

inline constexpr std::uint32_t kFslibVersion = 1;

class Library {
 public:
  std::vector<Model> models;

  const Model* find(const std::string& name) const;  // nullptr when absent
  void add(Model model);                             // throws fs::Error on a duplicate name

  std::vector<std::uint8_t> to_bytes() const;
  void save(const std::filesystem::path& path) const;
  // Throws fs::Error "source: at byte N: what" for truncated, corrupt or wrong-version data.
  static Library from_bytes(std::span<const std::uint8_t> bytes, const std::string& source);
  static Library load(const std::filesystem::path& path);
};

}  // namespace fs::host
