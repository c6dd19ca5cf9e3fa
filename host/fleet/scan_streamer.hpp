#pragma once
// `serve --nats --stream`: each scan goes into the fleet while the scanner streams it
// (docs/fleet.md#streamed-scans), so that only its last part is left to move when it ends.
//
//  * At the scan's ScanBegin its SCANS message is published: empty, message id streamed_scan_id, header
//    Facetscan-Parts naming the subject of its parts. A worker takes it at once and reads the parts as they
//    come.
//  * The scan's frames follow as parts of about `part_bytes` in PARTS (facetscan.parts.<scanner>.<scan id>,
//    message id "<scan id>-p<n>", header Facetscan-Part n): the .fscan file header, the ScanBegin and the
//    stripes in arrival order, so the parts joined are a .fscan image. The last part holds the ScanEnd (when
//    the scan has one) and carries Facetscan-Last and the scan's status.
//  * The calls come from the stream server's thread and never block it: a thread of the streamer publishes
//    the parts in order, each until the stream acknowledges it.
//  * A stream that fails (the server away, a publish refused, more than `max_queued_bytes` waiting) is
//    abandoned: its remaining parts are dropped and a last part with status "abandoned" is published (when
//    the server is away, as soon as it is back), so that the worker holding the scan drops it. The gateway
//    sends the scan whole through its spool instead: one result either way.
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "common/wire.hpp"
#include "host/fleet/nats_connection.hpp"
#include "host/fleet/streams.hpp"
#include "host/io/scan.hpp"

namespace fs::host::fleet {

struct StreamOutcome {
  bool stored = false;      // every part is in PARTS, the last one too: a worker will recognize the scan
  std::string scan_id;      // streamed_scan_id
  std::uint64_t nonce = 0;  // its nonce: a scan sent whole after its stream failed keeps the id
  std::string scanner;      // the scanner id it was streamed under
  std::string error;        // why the stream was abandoned
  std::size_t parts = 0;
  std::uint64_t bytes = 0;
  double last_ms = 0.0;  // end() until the stream acknowledged the last part
};

class ScanStreamer {
 public:
  ScanStreamer(NatsConnection& connection, const FleetSettings& settings, std::size_t part_bytes = 256 << 10,
               std::size_t max_queued_bytes = std::size_t(64) << 20);
  ~ScanStreamer();
  ScanStreamer(const ScanStreamer&) = delete;
  ScanStreamer& operator=(const ScanStreamer&) = delete;

  // The stream server's thread. begin() starts a scan's stream (one left open is abandoned); stripe() adds a
  // stripe of it; end() closes it with the delivered scan and returns its token for wait() (0 when the scan
  // is not the one streaming: its ScanBegin was not seen). abandon() gives up the open stream (the scan is
  // not taken).
  void begin(const std::string& scanner_id, const msg::ScanBegin& begin);
  void stripe(const msg::Stripe& stripe);
  std::uint64_t end(const Scan& scan);
  void abandon(const std::string& why);
  // The id of the open stream (streamed_scan_id), empty when none (the stream server's thread).
  std::string open_scan_id() const;

  // Any thread: waits until the stream `token` is stored or abandoned.
  StreamOutcome wait(std::uint64_t token);

 private:
  enum class Kind { Item, Part, Last };
  struct Task {
    std::uint64_t token = 0;
    Kind kind = Kind::Part;
    std::vector<std::uint8_t> bytes;
    std::string status;  // Last: the scan's status or "abandoned"
    std::chrono::steady_clock::time_point queued;
  };
  struct State {  // the publishing thread's view of one stream
    std::string scan_id, scanner, parts_subject;
    std::uint64_t nonce = 0;
    std::uint64_t next_part = 0;
    bool failed = false;
    bool item_sent = false;  // its SCANS message was published (or tried: it may be stored)
    std::string error;
    std::size_t parts = 0;
    std::uint64_t bytes = 0;
  };

  void push(Task task);
  void flush_part(Kind kind, std::string status = {});
  void run();
  void publish(State& s, const Task& t);  // throws fs::Error when the stream did not store it
  void finish(std::uint64_t token, StreamOutcome outcome);
  // The last part "abandoned" of a failed stream, so that the worker holding its scan drops it; false when
  // it could not be published (retried every 250 ms while the gateway runs; the thread's own list).
  bool announce_abandoned(State& s);

  NatsConnection& connection_;
  FleetSettings settings_;
  const std::size_t part_bytes_, max_queued_bytes_;
  std::mt19937_64 rng_;

  // The stream server's thread only: the open stream and its part being filled.
  std::uint64_t open_ = 0;
  std::uint64_t open_scan_ = 0;
  std::string open_id_;
  wire::VectorSink part_;
  std::uint32_t frame_seq_ = 0;
  std::vector<std::uint8_t> frame_;

  std::mutex mu_;
  std::condition_variable cv_;    // tasks for the thread
  std::condition_variable done_;  // outcomes
  std::deque<Task> tasks_;
  std::size_t queued_bytes_ = 0;
  std::map<std::uint64_t, std::string> overflow_;  // streams abandoned for the queue bound (mu_)
  std::map<std::uint64_t, StreamOutcome> outcomes_;
  std::map<std::uint64_t, State> states_;  // publishing thread (created by begin() under mu_)
  std::vector<State> pending_;             // publishing thread: abandoned streams not announced yet
  static constexpr std::size_t kMaxPending = 1024;
  std::uint64_t next_token_ = 1;
  bool parts_checked_ = false;  // PARTS exists (checked once it could be)
  bool stop_ = false;
  bool exited_ = false;  // the thread is gone: wait() returns
  std::thread thread_;
};

}  // namespace fs::host::fleet
