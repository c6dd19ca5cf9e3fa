#pragma once
// The last N recognized scans, as immutable snapshots shared with the HTTP threads: the recognizer's thread
// builds a ScanRecord once (JSON text, downsampled points) and adds it; readers take a shared_ptr and never
// hold the lock while they send. Memory is bounded: at most `capacity` records, each with at most
// ScanRecord::kMaxPoints points (see scene_data.hpp).
#include <cstddef>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace fs::host::web {

struct ScanRecord {
  std::uint64_t id = 0;             // 1, 2, ... in this process (the API's ID)
  std::uint64_t scan_id = 0;        // the scanner's scan id
  std::int64_t result_unix_ms = 0;  // when the recognition result existed (system clock, ms)
  std::string summary_json;         // one line of /api/scans (see api.hpp)
  std::string detail_json;          // /api/scans/ID
  std::string points;               // /api/scans/ID/points (binary, see scene_data.hpp)
  std::filesystem::path dir;        // the scan's output folder (report/, result.json); empty = none
  std::filesystem::path recording;  // the .fscan holding the scan; empty = none
  std::size_t bytes() const { return summary_json.size() + detail_json.size() + points.size(); }
};

class ScanHistory {
 public:
  explicit ScanHistory(std::size_t capacity) : capacity_(capacity == 0 ? 1 : capacity) {}
  // Adds a record (evicting the oldest beyond capacity), or replaces the one with the same id; returns the
  // number of records evicted.
  std::size_t add(std::shared_ptr<const ScanRecord> record);
  std::shared_ptr<const ScanRecord> find(std::uint64_t id) const;
  std::shared_ptr<const ScanRecord> latest() const;
  std::vector<std::shared_ptr<const ScanRecord>> newest_first() const;
  std::size_t size() const;
  std::size_t capacity() const { return capacity_; }
  std::size_t bytes() const;  // held by the records

 private:
  std::size_t capacity_;
  mutable std::mutex mutex_;
  std::deque<std::shared_ptr<const ScanRecord>> records_;  // oldest first
};

}  // namespace fs::host::web
