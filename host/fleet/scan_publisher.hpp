#pragma once
// Publishes completed scans (.fscan images) to the SCANS stream: subject facetscan.scans.<scanner-id>,
// message id scan_message_id(scanner, scan id, start time, digest of the image) so that a re-sent scan is
// stored once. The gateway (`serve --nats`) calls publish() per completed scan; `facetscan submit` publishes
// files the same way.
//
// One message per scan: the shipped server config raises max_payload to 8 MB (a 500-stripe scan is ~6 MB;
// docs/fleet.md#payload has the measured cost). A scan larger than the server's max_payload is an error
// naming both sizes (it is not split).
#include <cstdint>
#include <span>
#include <string>

#include "host/fleet/nats_connection.hpp"
#include "host/fleet/streams.hpp"

namespace fs::host::fleet {

struct PublishedScan {
  std::string message_id;  // scan_message_id(...), or "<scan id>-whole" for a streamed scan sent whole
  std::string scan_id;     // the scan's id (Facetscan-Scan-Id; its result's id)
  std::string subject;
  std::uint64_t sequence = 0;  // in SCANS (of the first copy when duplicate)
  bool duplicate = false;      // the stream already held this scan (a re-send): stored once
  std::size_t bytes = 0;
  double ms = 0.0;  // publish until the stream's acknowledgement
};

class ScanPublisher {
 public:
  // Checks the scanner id and the SCANS stream (created when missing and the user may).
  ScanPublisher(NatsConnection& connection, std::string scanner_id, const FleetSettings& settings = {});

  // Publishes one scan image; `status` is "complete" or the partial scan's status (Scan status name), carried
  // in a header. Blocks until the stream acknowledges (JetStream: stored on disk, replicated). Retries a
  // timed-out publish (the server restarting) `retries` times with the same message id, then throws.
  // `scan_id` (a streamed scan sent whole, its stream failed): the scan keeps that id (Facetscan-Scan-Id,
  // hence its result's id) and is stored under message id "<scan_id>-whole".
  PublishedScan publish(std::span<const std::uint8_t> fscan, const std::string& status = "complete",
                        int retries = 20, const std::string& scan_id = {});

  const std::string& scanner_id() const { return scanner_id_; }

 private:
  NatsConnection& connection_;
  std::string scanner_id_;
  std::string subject_;
};

}  // namespace fs::host::fleet
