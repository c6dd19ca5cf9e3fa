// Fuzz target: the .fslib reader must reject any byte string with fs::Error, never crash or hang.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>

#include "common/error.hpp"
#include "host/library/library.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const auto lib = fs::host::Library::from_bytes(std::span<const std::uint8_t>(data, size), "fuzz.fslib");
    // Whatever loads serializes as the current version: the same bytes when it was that version (its stored
    // arc index describes its models, so it is written back as read); a version 1 file gains the index and a
    // version 2 file's is built again, and that file loads and serializes to itself.
    const auto again = lib.to_bytes();
    const bool older = data[8] < fs::host::kFslibVersion;  // (the version's other bytes are 0: it loaded)
    if (older) {
      const auto current = fs::host::Library::from_bytes(again, "again.fslib");
      if (!current.index_describes_models() || current.to_bytes() != again) __builtin_trap();
    } else if (again.size() != size || !std::equal(again.begin(), again.end(), data)) {
      __builtin_trap();
    }
  } catch (const fs::Error&) {
  }
  return 0;
}
