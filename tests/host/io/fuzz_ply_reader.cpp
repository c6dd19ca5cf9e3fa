// Fuzz target: the PLY reader must either read a cloud or throw fs::Error, never crash or hang.
#include <cstddef>
#include <cstdint>
#include <span>

#include "common/error.hpp"
#include "host/io/cloud_readers.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fs::host::OrganizedCloud cloud;
  fs::host::CloudReadOptions options;
  options.max_points = 1u << 20;  // keep the fuzzer's memory bounded
  try {
    fs::host::read_ply(std::span(reinterpret_cast<const std::byte*>(data), size), "fuzz.ply", cloud, options);
    if (cloud.points.size() != std::size_t(cloud.width) * cloud.height) __builtin_trap();
    if (cloud.has_labels() && cloud.labels.size() != cloud.points.size()) __builtin_trap();
  } catch (const fs::Error&) {
  }
  return 0;
}
