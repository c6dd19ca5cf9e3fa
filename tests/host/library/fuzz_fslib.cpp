// Fuzz target: the .fslib reader must reject any byte string with fs::Error, never crash or hang.
#include <cstddef>
#include <cstdint>
#include <span>

#include "common/error.hpp"
#include "host/library/library.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const auto lib = fs::host::Library::from_bytes(std::span<const std::uint8_t>(data, size), "fuzz.fslib");
    // Whatever loads must serialize back to the same bytes.
    const auto again = lib.to_bytes();
    if (again.size() != size) __builtin_trap();
  } catch (const fs::Error&) {
  }
  return 0;
}
