#pragma once
// Builds Scans from decoded messages, for the .fscan reader and the live TCP stream alike. A scan is
// delivered through the callback when it ends: ScanEnd (complete / aborted / missing stripes), a new
// ScanBegin before ScanEnd (superseded) or end_of_stream() (disconnected mid-scan -> partial). The Scan
// passed to the callback is reused afterwards: copy what you need to keep.
#include <cstdint>
#include <functional>
#include <string>

#include "common/wire.hpp"
#include "host/io/scan.hpp"

namespace fs {
class ScanFileReader;
}

namespace fs::host {

struct AssemblerStats {
  std::uint64_t scans_complete = 0;
  std::uint64_t scans_partial = 0;
  std::uint64_t orphan_stripes = 0;  // stripes / ends with no matching ScanBegin
  std::uint64_t heartbeats = 0;
  std::uint64_t faults = 0;
  std::int64_t last_heartbeat_ns = 0;
  std::uint8_t last_state = 0;  // firmware state from the last heartbeat
};

class ScanAssembler {
 public:
  using Callback = std::function<void(const Scan&)>;
  explicit ScanAssembler(Callback on_scan, ScanLimits limits = {});

  void on_message(const wire::DecodedMessage& m);
  void on_scan_begin(const msg::ScanBegin& m);
  void on_stripe(const msg::Stripe& m);
  void on_scan_end(const msg::ScanEnd& m);
  void on_heartbeat(const msg::Heartbeat& m);
  void on_fault(const msg::Fault& m);
  // The source closed: a scan in progress is delivered as partial (Disconnected, or `why`).
  void end_of_stream(ScanStatus why = ScanStatus::Disconnected);

  bool in_scan() const { return scan_.started() && scan_.status() == ScanStatus::InProgress; }
  const Scan& current() const { return scan_; }
  Scan& storage() { return scan_; }  // to reserve() up front
  const AssemblerStats& stats() const { return stats_; }

 private:
  void deliver();
  Callback on_scan_;
  ScanLimits limits_;
  Scan scan_;
  AssemblerStats stats_;
};

// Reads every scan of a .fscan file through an assembler; returns the number of scans delivered. Errors in
// the file are fs::Error "<path>: at byte N: ..." (a scan in progress at a clean end of file is partial),
// among them a ScanBegin whose scan exceeds `limits` (the memory budget), refused before any allocation.
std::size_t read_scan_file(const std::string& path, const ScanAssembler::Callback& on_scan,
                           const ScanLimits& limits = {});
// The first scan of a .fscan file into `out` (moved, not copied); throws when the file has no scan.
void load_scan(const std::string& path, Scan& out, const ScanLimits& limits = {});
// The same for any .fscan reader (a file or an image in memory); `name` labels its errors.
void load_first_scan(ScanFileReader& reader, const std::string& name, Scan& out,
                     const ScanLimits& limits = {});

}  // namespace fs::host
