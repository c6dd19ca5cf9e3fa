// Fuzz target: fault spec strings (CLI --fault, config "faults"). Must either parse or throw fs::Error.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "common/error.hpp"
#include "hw-sim/sim_faults.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const auto f = fs::sim::parse_fault_spec(std::string_view(reinterpret_cast<const char*>(data), size));
    if (f.count < 0) __builtin_trap();
  } catch (const fs::Error&) {
  }
  return 0;
}
