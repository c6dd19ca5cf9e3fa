// Fuzz target: facetscan-fw JSON configuration. Must either apply or throw fs::Error.
#include <cstddef>
#include <cstdint>
#include <string>

#include "common/error.hpp"
#include "firmware/fw_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fs::fw::FwConfig cfg;
  try {
    fs::fw::apply_config_json(cfg, std::string(reinterpret_cast<const char*>(data), size), "fuzz.json");
    if (cfg.loop.period <= 0) __builtin_trap();
  } catch (const fs::Error&) {
  }
  return 0;
}
