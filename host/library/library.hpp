#pragma once
// A library of reference models and its versioned binary file (.fslib).
//
// .fslib layout (little-endian): "FSLIB\r\n\x1a" (8 bytes), u32 version (3; 1 and 2 are still read), u32
// model count, u64 payload size, u32 CRC-32 of the payload, then the payload: per model: string name, u8
// open, u32 face count, per face (normal 3 f64, offset f64, area f64, centroid 3 f64, u32 loop count, per
// loop u32 vertex count + 3 f64 each), u32 arc count, per arc (u32 a, u32 b, f64 border), u32 symmetry count,
// 9 f64 each (row major). Strings are u32 length + bytes. Totals, centre and radius are recomputed on load.
// Version 2 adds the library's arc index (match::ArcIndex) after the models: u32 entry count, per entry
// f32 angle, f32 a0, f32 a1, u32 reference; u32 path count, per path 6 f32; per reference + 1 u32 path start;
// per reference f32 flattest angle; per reference u32 fingerprint of the model's graph (ArcIndex::describes).
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "host/library/model.hpp"
#include "host/match/arc_index.hpp"

namespace fs::host {

// 3: the arc index counts shallow folds in its areas (match::kAreaFoldMaxDeg); a version 2 file's index (face
// areas alone) is checked and dropped when read, so the recognizer builds one.
inline constexpr std::uint32_t kFslibVersion = 3;

class Library {
 public:
  std::vector<Model> models;
  // The arc index of the models (read from a version 3 file, or build_index()); the recognizer uses it when
  // it describes the models (ArcIndex::describes) and builds its own otherwise.
  match::ArcIndex index;

  match::ArcIndex index_of_models() const;  // built now
  void build_index();                       // index = index_of_models()
  bool index_describes_models() const;

  const Model* find(const std::string& name) const;  // nullptr when absent
  void add(Model model);                             // throws fs::Error on a duplicate name

  // kFslibVersion, with the arc index (built for the file when `index` does not describe the models).
  std::vector<std::uint8_t> to_bytes() const;
  void save(const std::filesystem::path& path) const;
  // Throws fs::Error "source: at byte N: what" for truncated, corrupt or wrong-version data.
  static Library from_bytes(std::span<const std::uint8_t> bytes, const std::string& source);
  static Library load(const std::filesystem::path& path);
};

}  // namespace fs::host
