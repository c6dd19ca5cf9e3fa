#pragma once
// Names of the fleet: streams, subjects, message ids (docs/fleet.md#subjects-and-ids).
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace fs::host::fleet {

inline constexpr const char* kScansStream = "SCANS";        // work queue of .fscan images
inline constexpr const char* kResultsStream = "RESULTS";    // recognition results (JSON)
inline constexpr const char* kDeadStream = "DEAD";          // scans that failed MaxDeliver times
inline constexpr const char* kPartsStream = "PARTS";        // the parts of streamed scans (docs/fleet.md)
inline constexpr const char* kWorkersConsumer = "workers";  // the durable pull consumer all workers share
inline constexpr const char* kScansPrefix = "facetscan.scans.";
inline constexpr const char* kResultsPrefix = "facetscan.results.";
inline constexpr const char* kDeadPrefix = "facetscan.dead.";
inline constexpr const char* kPartsPrefix = "facetscan.parts.";

// Message headers (besides JetStream's Nats-Msg-Id).
inline constexpr const char* kHeaderScanId = "Facetscan-Scan-Id";
inline constexpr const char* kHeaderScanner = "Facetscan-Scanner";
inline constexpr const char* kHeaderStatus = "Facetscan-Scan-Status";  // complete | partial status name
inline constexpr const char* kHeaderReason = "Facetscan-Reason";       // dead letters
// A streamed scan (serve --nats --stream): its SCANS message is empty and names the subject of its parts;
// each part carries its number, the last one also "Facetscan-Last" and the scan's status (or "abandoned").
inline constexpr const char* kHeaderParts = "Facetscan-Parts";
inline constexpr const char* kHeaderPart = "Facetscan-Part";
inline constexpr const char* kHeaderLast = "Facetscan-Last";
inline constexpr const char* kStatusAbandoned = "abandoned";  // the gateway sends this scan whole instead

// A scanner id is one subject token (and one MQTT topic level): 1..64 of [A-Za-z0-9_-]. Throws fs::Error
// naming `what` otherwise (ids are checked, never rewritten: two scanners must not map to one subject).
void check_scanner_id(std::string_view id, const char* what = "scanner id");

// The fleet-wide id of a scan: "<scanner-id>-<scan id>-<start time ns>-<digest, 8 hex>" (the ScanBegin's scan
// id and start time; image_digest of the .fscan image). It is the SCANS message id (a re-sent scan, byte for
// byte the same, is stored once) and the RESULTS message id (a redelivered scan yields one result). The
// digest keeps two different scans with the same scan id and start time apart (a scanner whose counter and
// clock restarted; every hw-sim recording on virtual time is scan 1 at t = 1 s): without it the second would
// be dropped as a duplicate.
std::string scan_message_id(std::string_view scanner_id, std::uint64_t scan_id, std::int64_t start_time_ns,
                            std::span<const std::uint8_t> image);
// The digest of a .fscan image in scan ids: CRC-32 (zlib, ISO-HDLC polynomial). Not CRC-32C: every frame of
// an image ends with the CRC-32C of its bytes, and a CRC-32C over such frames depends only on their lengths
// (the CRC residue), so two different scans with equal frame sizes would get the same CRC-32C.
std::uint32_t image_digest(std::span<const std::uint8_t> image);
// The id of a streamed scan, fixed at its ScanBegin (no digest of the image exists yet):
// "<scanner-id>-<scan id>-<start time ns>-s<nonce, 16 hex>", the nonce drawn by the gateway per scan. A
// streamed scan is never re-sent under this id (a stream that fails is abandoned and the scan sent whole).
std::string streamed_scan_id(std::string_view scanner_id, std::uint64_t scan_id, std::int64_t start_time_ns,
                             std::uint64_t nonce);

inline std::string scans_subject(std::string_view scanner_id) {
  return std::string(kScansPrefix) + std::string(scanner_id);
}
inline std::string results_subject(std::string_view scanner_id) {
  return std::string(kResultsPrefix) + std::string(scanner_id);
}
inline std::string dead_subject(std::string_view scanner_id) {
  return std::string(kDeadPrefix) + std::string(scanner_id);
}
// The subject of a streamed scan's parts: facetscan.parts.<scanner-id>.<scan id (streamed_scan_id)>.
inline std::string parts_subject(std::string_view scanner_id, std::string_view scan_id) {
  return std::string(kPartsPrefix) + std::string(scanner_id) + "." + std::string(scan_id);
}
// The message id of part `n` of a streamed scan: "<scan id>-p<n>".
std::string part_message_id(std::string_view scan_id, std::uint64_t n);
// The scanner id of a subject "<prefix><id>", or "" when the subject does not start with prefix.
std::string scanner_of_subject(std::string_view subject, std::string_view prefix);

}  // namespace fs::host::fleet
