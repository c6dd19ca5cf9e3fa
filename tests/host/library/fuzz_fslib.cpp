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
    // Whatever loads serializes as version 2: the same bytes when it was version 2 (its stored arc index
    // describes its models, so it is written back as read); a version 1 file gains the index, and that file
    // loads and serializes to itself.
    const auto again = lib.to_bytes();
    const bool version1 = data[8] == 1;  // (the version's other bytes are 0: it loaded)
    if (version1) {
      const auto v2 = fs::host::Library::from_bytes(again, "again.fslib");
      if (!v2.index_describes_models() || v2.to_bytes() != again) __builtin_trap();
    } else if (again.size() != size || !std::equal(again.begin(), again.end(), data)) {
      __builtin_trap();
    }
  } catch (const fs::Error&) {
  }
  return 0;
}
