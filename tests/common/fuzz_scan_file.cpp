// libFuzzer target: the .fscan reader on an arbitrary file image.
#include <cstdint>
#include <span>

#include "common/scan_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static fs::wire::DecodedMessage msg;
  try {
    fs::ScanFileReader reader(std::span<const std::uint8_t>(data, size), "fuzz.fscan",
                              fs::wire::DecoderLimits{16384});
    while (reader.next(msg)) {
    }
  } catch (const fs::Error&) {
  }
  return 0;
}
