// Fuzz target: the --galvo / --camera spec parsers. Bad specs must throw fs::Error, nothing else.
#include <cstdint>
#include <string_view>

#include "common/error.hpp"
#include "firmware/backends/factory.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view s(reinterpret_cast<const char*>(data), size);
  try {
    (void)fs::fw::parse_gpio_spec(s);
  } catch (const fs::Error&) {
  }
  try {
    (void)fs::fw::parse_can_spec(s);
  } catch (const fs::Error&) {
  }
  try {
    (void)fs::fw::parse_v4l2_spec(s);
  } catch (const fs::Error&) {
  }
  try {
    (void)fs::fw::parse_gpio_laser_spec(s);
  } catch (const fs::Error&) {
  }
  return 0;
}
