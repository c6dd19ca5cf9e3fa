#pragma once
// Reads the fleet's results (RESULTS) or dead letters (DEAD) in stream order through an ordered consumer:
// `facetscan results`, `facetscan submit --wait`. Read-only: the shop-floor user may use it.
#include <cstdint>
#include <optional>
#include <string>

#include "host/fleet/nats_connection.hpp"

namespace fs::host::fleet {

struct FleetResult {
  std::string subject;
  std::string scanner_id;
  std::string scan_id;
  std::string body;    // RESULTS: the result JSON; DEAD: the .fscan image
  std::string reason;  // DEAD: why
  std::uint64_t sequence = 0;
  std::uint64_t pending = 0;  // stored messages of the filter not yet read after this one
};

class ResultsReader {
 public:
  enum class Source { Results, Dead };
  // scanner_id "" = every scanner. From the first stored message (the stream keeps results for a week).
  ResultsReader(NatsConnection& connection, Source source, const std::string& scanner_id = {});
  ~ResultsReader();
  ResultsReader(const ResultsReader&) = delete;
  ResultsReader& operator=(const ResultsReader&) = delete;

  // The next message, or nothing after timeout_ms.
  std::optional<FleetResult> next(std::int64_t timeout_ms);
  // Stored messages of the stream (all subjects) when the reader was made: 0 = nothing to read yet.
  std::uint64_t stored_at_start() const { return stored_at_start_; }

 private:
  NatsConnection& connection_;
  natsSubscription* sub_ = nullptr;
  std::uint64_t stored_at_start_ = 0;
};

// One line per result: "<scanner> <scan id>: N object(s)  model (x, y, z) confidence ...  [worker W]", or for
// a dead letter "<scanner> <scan id>: DEAD (N bytes): reason".
std::string result_summary_line(const FleetResult& r, bool dead = false);

}  // namespace fs::host::fleet
