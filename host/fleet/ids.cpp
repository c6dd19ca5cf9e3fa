#include "host/fleet/ids.hpp"

#include <fmt/format.h>

#include "common/crc32_ieee.hpp"
#include "common/error.hpp"

namespace fs::host::fleet {

void check_scanner_id(std::string_view id, const char* what) {
  if (id.empty() || id.size() > 64)
    throw Error(fmt::format("{} '{}': 1 to 64 characters of A-Z a-z 0-9 _ -", what, id));
  for (char c : id) {
    const bool ok =
        (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
    if (!ok)
      throw Error(
          fmt::format("{} '{}': only A-Z a-z 0-9 _ - (it is a NATS subject token and an MQTT topic "
                      "level)",
                      what, id));
  }
}

std::uint32_t image_digest(std::span<const std::uint8_t> image) { return crc32_ieee(image); }

std::string scan_message_id(std::string_view scanner_id, std::uint64_t scan_id, std::int64_t start_time_ns,
                            std::span<const std::uint8_t> image) {
  return fmt::format("{}-{}-{}-{:08x}", scanner_id, scan_id, start_time_ns, image_digest(image));
}

std::string streamed_scan_id(std::string_view scanner_id, std::uint64_t scan_id, std::int64_t start_time_ns,
                             std::uint64_t nonce) {
  return fmt::format("{}-{}-{}-s{:016x}", scanner_id, scan_id, start_time_ns, nonce);
}

std::string part_message_id(std::string_view scan_id, std::uint64_t n) {
  return fmt::format("{}-p{}", scan_id, n);
}

std::string scanner_of_subject(std::string_view subject, std::string_view prefix) {
  if (subject.size() <= prefix.size() || subject.substr(0, prefix.size()) != prefix) return {};
  return std::string(subject.substr(prefix.size()));
}

}  // namespace fs::host::fleet
