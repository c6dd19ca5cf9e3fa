#pragma once
// The gateway's disk spool (docs/fleet.md#gateway): every scan `serve --nats` receives is written here first
// and removed only when the SCANS stream has stored it, so a scan survives an unreachable server and a
// gateway restart. Bounded: put() is refused (has_room() false) when the scan would take the spool over
// max_bytes, except into an empty spool (one scan always fits); the gateway then holds the scanners (TCP
// back-pressure).
//
// Files, in publishing order:  DIR/<sequence, 12 digits>_<scanner id>_<status token>[_s<nonce>].fscan
// (the nonce: a streamed scan's, see SpoolEntry::stream_nonce)
// A scan is written to DIR/.partial-<sequence> and renamed into place after fsync: a crash mid-write leaves
// only a .partial file (removed at the next open; that scan was never taken from the scanner's point of view:
// the gateway had not published it). Scans the server can never take (larger than its max_payload) are moved
// to DIR/rejected/ with a .reason text next to them: kept, reported, not retried.
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "host/io/scan.hpp"

namespace fs::host::fleet {

struct SpoolEntry {
  std::filesystem::path path;
  std::uint64_t sequence = 0;
  std::string scanner_id;
  ScanStatus status = ScanStatus::Complete;
  std::uint64_t bytes = 0;
  // A streamed scan whose stream failed (serve --nats --stream): the nonce of its streamed id, which it keeps
  // when sent whole, so that it gets one result even if its stream reached a worker after all.
  std::optional<std::uint64_t> stream_nonce;
};

// "complete", "aborted", "missing-stripes", ... (file-name safe) and back; parse throws fs::Error.
const char* status_token(ScanStatus s);
ScanStatus parse_status_token(const std::string& token);

class ScanSpool {
 public:
  // Creates DIR when missing and takes over the scans a previous run left (in their order). Throws fs::Error
  // naming DIR when it cannot be created or written.
  ScanSpool(std::filesystem::path dir, std::uint64_t max_bytes);

  bool has_room(std::uint64_t bytes) const;
  // Writes one scan (fsync'd) and returns its entry. Throws fs::Error naming the file on an I/O error (disk
  // full): the caller keeps the scan.
  SpoolEntry put(std::span<const std::uint8_t> image, const std::string& scanner_id, ScanStatus status,
                 std::optional<std::uint64_t> stream_nonce = std::nullopt);
  std::optional<SpoolEntry> oldest() const;
  // The image of an entry; throws fs::Error naming the file.
  std::vector<std::uint8_t> read(const SpoolEntry& entry) const;
  // The scan is stored in the stream: its file goes.
  void remove(const SpoolEntry& entry);
  // The scan can never be published: moved to DIR/rejected/ with `reason` in <name>.reason.
  std::filesystem::path reject(const SpoolEntry& entry, const std::string& reason);

  std::size_t count() const;
  std::uint64_t bytes() const;
  std::uint64_t max_bytes() const { return max_bytes_; }
  std::size_t rejected() const;
  const std::filesystem::path& dir() const { return dir_; }

 private:
  void forget(std::uint64_t sequence);  // drops an entry from the list (mu_ held)

  std::filesystem::path dir_;
  std::uint64_t max_bytes_;
  mutable std::mutex mu_;
  std::vector<SpoolEntry> entries_;  // ascending sequence
  std::uint64_t bytes_ = 0;
  std::uint64_t next_sequence_ = 1;
  std::size_t rejected_ = 0;
};

}  // namespace fs::host::fleet
