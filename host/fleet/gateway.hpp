#pragma once
// The gateway half of `facetscan serve --nats` (docs/fleet.md#gateway): every scan the scanners stream is
// encoded as a .fscan image, written to the disk spool (scan_spool.hpp) and published from there to SCANS
// (facetscan.scans.<scanner-id>, message id scan_message_id) by a sender thread; its file goes when the
// stream has stored it. While the server is unreachable scans stay in the spool (its size is logged) and are
// sent, oldest first, when it returns, also after a gateway restart. When the spool is full, submit() waits:
// serve's queue fills and the stream server stops reading the scanners (TCP back-pressure), so nothing is
// dropped.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "host/fleet/nats_connection.hpp"
#include "host/fleet/scan_publisher.hpp"
#include "host/fleet/scan_spool.hpp"
#include "host/fleet/scan_streamer.hpp"
#include "host/fleet/streams.hpp"
#include "host/io/scan.hpp"

namespace fs::host::fleet {

struct GatewayOptions {
  NatsOptions nats;
  // The scanner id of every scan; empty = one id per scanner address: the peer's IP with '.' and ':' as '-'
  // ("10-0-3-17"), so that two scanners never share a subject.
  std::string scanner_id;
  std::filesystem::path spool_dir = "facetscan-spool";
  std::uint64_t spool_max_bytes = std::uint64_t(2) << 30;
  FleetSettings settings;
  // --stream: each scan goes into the fleet while it streams (scan_streamer.hpp); a stream that fails is sent
  // whole through the spool.
  bool stream = false;
  std::size_t part_bytes = 256 << 10;
  bool quiet = false;
  std::function<void(const std::string&)> log;  // one line per event (without newline); stdout when empty
};

struct GatewayStats {
  std::uint64_t received = 0;         // scans handed to submit()
  std::uint64_t published = 0;        // stored by the stream (new), streamed or whole
  std::uint64_t streamed = 0;         // of them, streamed while they were scanned (--stream)
  std::uint64_t stream_failures = 0;  // streams abandoned: those scans went whole through the spool
  std::uint64_t duplicates = 0;  // the stream had them already (a re-send after a crash between publish and
                                 // spool removal): stored once
  std::uint64_t rejected = 0;    // moved to DIR/rejected/ (never publishable)
  std::uint64_t outages = 0;     // times the server became unreachable with scans to send
  std::size_t spooled = 0;       // scans in the spool now
  std::uint64_t spool_bytes = 0;
  std::uint64_t spool_peak_bytes = 0;
  std::vector<double> publish_ms;  // per published scan: publish until the stream's acknowledgement
                                   // (streamed: the scan's end until its last part's acknowledgement)
};

// The scanner id for a peer "ADDR:PORT" / "[V6]:PORT": the address with every character outside
// [A-Za-z0-9] as '-'.
std::string scanner_id_from_peer(const std::string& peer);

class Gateway {
 public:
  // Opens the spool (scans a previous run left are sent first) and connects in the background: the gateway
  // starts while the server is down. Throws fs::Error for a bad URL / TLS policy / spool directory.
  explicit Gateway(GatewayOptions options);
  ~Gateway();
  Gateway(const Gateway&) = delete;
  Gateway& operator=(const Gateway&) = delete;

  // --stream, from the stream server's thread: a frame of the scan in progress (StreamServerOptions::
  // on_scan_frame), and the scan delivered (`taken` false: serve does not take it). stream_end() returns the
  // token to pass to submit() (0: the scan was not streamed).
  void stream_frame(const std::string& peer, const wire::DecodedMessage& message);
  std::uint64_t stream_end(const Scan& scan, bool taken);

  // Spools one scan and returns (the sender publishes it). Waits while the spool is full unless `stopping`
  // (serve's shutdown: the scan is spooled over the bound rather than lost). Throws fs::Error when the scan
  // cannot be written (disk error): the caller reports it as failed. A streamed scan (`stream` from
  // stream_end) is only spooled when its stream failed.
  void submit(const Scan& scan, const std::string& peer, bool stopping, std::uint64_t stream = 0);
  // Shutting down: a submit() waiting for room in the spool goes ahead (over the bound) and later ones do not
  // wait. Call before joining the thread that calls submit().
  void release_waiters();
  // Waits up to `drain` for the spool to empty, then stops the sender; what is left stays on disk for the
  // next start. Returns the scans left.
  std::size_t stop(std::chrono::milliseconds drain);

  GatewayStats stats() const;
  const ScanSpool& spool() const { return spool_; }

 private:
  void send_loop();
  bool send_one(const SpoolEntry& entry);  // false: the server is unreachable (retry later)
  void log(const std::string& line) const;
  std::string scanner_of(const std::string& peer) const;
  std::string spool_text() const;

  GatewayOptions options_;
  ScanSpool spool_;
  std::unique_ptr<NatsConnection> connection_;
  std::map<std::string, std::unique_ptr<ScanPublisher>> publishers_;  // per scanner id (sender thread)
  std::unique_ptr<ScanStreamer> streamer_;                            // --stream
  mutable std::mutex mu_;
  std::condition_variable cv_;
  bool stop_ = false;
  bool released_ = false;     // release_waiters()
  bool unreachable_ = false;  // sender: in an outage (logged once)
  std::chrono::steady_clock::time_point drain_deadline_{};
  GatewayStats stats_;
  std::thread sender_;
};

}  // namespace fs::host::fleet
