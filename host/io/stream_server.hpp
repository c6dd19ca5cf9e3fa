#pragma once
// The host end of the live scanner stream: listens on ADDR:PORT (127.0.0.1 by default), accepts scanner
// connections (the firmware connects out, see firmware/stream/tcp_sink.hpp), decodes frames incrementally
// (one decoder per connection) and assembles scans, delivered through the callback as they end.
//
// Connections (the wire carries no scanner serial: a scanner is identified by the scan it streams):
//  * Up to max_clients connections are open and read at once (the listen backlog is the same number). At the
//    limit a new connection closes the oldest one that never sent a frame (an idle prober); when every open
//    connection has sent frames, the new one is refused (closed at once). Both are counted and logged.
//  * The connection whose ScanBegin started the scan in progress is the scanner ("owner"). Another
//    connection sending a Stripe / ScanEnd of that scan id resumes it (the scanner re-dialled: it resends
//    what it buffered, duplicates counted by the Scan) and becomes the owner; the old connection is closed.
//  * A ScanBegin from another connection while the owner is connected waits: that connection is not read
//    further (TCP back-pressure; the scanner buffers) until the scan in progress is delivered or its owner is
//    gone, then it starts its scan. Nothing is evicted or dropped. With the owner gone (within the reconnect
//    grace) a new ScanBegin supersedes the scan in progress, as a scanner that moved on does.
//  * Heartbeats from any connection count; a Fault from a connection that is not the owner of the scan in
//    progress is ignored (counted in ignored_frames). Stripes / ScanEnds of other scan ids are orphans.
//
// Link handling:
//  * The host sends every connection a Heartbeat frame every heartbeat_interval_ms (the scanner may
//    require them), also while frames are held (below).
//  * A connection silent for link_timeout_ms (no frame, not even a scanner heartbeat) is closed. A connection
//    whose next frame the server holds (waiting ScanBegin, back-pressure) is not timed out for that pause.
//  * A closed / lost owner leaves the scan in progress open for reconnect_grace_ms: the scanner reconnects
//  and
//    resends what it buffered, and the scan continues (possibly to completion). When the grace expires, the
//    scan is delivered as partial (ScanStatus::Disconnected). grace 0 = deliver at once.
//  * A malformed frame (bad CRC, unknown version, absurd length) closes that connection (protocol error,
//    counted, last_error names the peer, on_protocol_error is told); the scanner reconnects and resends. A
//    scan cut by it that is not resumed ends as ScanStatus::ProtocolError (not Superseded / Disconnected).
//  * A ScanBegin the limits refuse (ScanLimits: step count, camera size, memory budget) is not a protocol
//    error: on_refused is told (peer, the ScanBegin, reason), the connection stays, the scan's stripes and
//    ScanEnd are orphans.
//  * Back-pressure: while can_deliver() returns false (the consumer's queue is full) every frame that could
//    deliver a scan (ScanBegin, ScanEnd of the scan in progress) is held with the rest of its connection's
//    stream, and grace expiry waits; stripes keep flowing into the scan in progress, heartbeats go on.
//  * The scan callback handles its own processing errors; an exception escaping it is counted (scan_errors,
//    last_scan_error) and is neither a protocol error nor the end of the connection or of the server.
// One thread: run() or poll_once() in the caller's thread; stop() and wake() may be called from any thread.
// The clock is injectable for tests.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "common/wire.hpp"
#include "host/io/scan_assembler.hpp"
#include "host/io/scan_limits.hpp"

namespace fs::host {

struct StreamServerOptions {
  std::string listen = "127.0.0.1:5555";  // ADDR:PORT; port 0 picks a free port (see port())
  std::int64_t heartbeat_interval_ms = 500;
  std::int64_t link_timeout_ms = 3000;
  std::int64_t reconnect_grace_ms = 5000;
  int max_clients = 4;  // connections open at once (also the listen backlog)
  ScanLimits limits;
  // After delivering a scan larger than this working size, the assembler's scan storage is released back to
  // it (Scan::release_storage; the caller's malloc_trim returns the pages). Off by default.
  bool release_large_scans = false;
  WorkingSize working_size;
  std::function<std::int64_t()> now_ns;  // monotonic clock; default CLOCK_MONOTONIC
  // Called for every protocol error, before the connection is closed: (peer "ADDR:PORT", reason).
  std::function<void(const std::string& peer, const std::string& reason)> on_protocol_error;
  // Connection policy events, for the log: refused / closed / waiting connections, resumed scans.
  std::function<void(const std::string& peer, const std::string& what)> on_notice;
  // A ScanBegin refused by the limits: (peer, the ScanBegin, reason).
  std::function<void(const std::string& peer, const msg::ScanBegin& begin, const std::string& reason)>
      on_refused;
  // Back-pressure: false while the consumer cannot take another scan. Default: always.
  std::function<bool()> can_deliver;
  // The scan in progress frame by frame, for a consumer that forwards it while it streams (serve --nats
  // --stream): the accepted ScanBegin, then each Stripe of that scan (a resumed scanner's resent duplicates
  // too) right after the assembler took it: (peer, message). The ScanEnd is not passed: the scan callback
  // follows it with the whole scan. An exception escaping it counts as a scan error.
  std::function<void(const std::string& peer, const wire::DecodedMessage& message)> on_scan_frame;
};

struct StreamServerStats {
  std::uint64_t connections = 0;
  std::uint64_t disconnects = 0;          // peer closed or errored
  std::uint64_t link_timeouts = 0;        // closed for silence
  std::uint64_t protocol_errors = 0;      // closed for a malformed frame
  std::uint64_t refused_connections = 0;  // closed at accept: max_clients connections were streaming
  std::uint64_t idle_closed = 0;          // closed without ever sending a frame, to make room
  std::uint64_t resumed = 0;              // a new connection took over the scan in progress
  std::uint64_t waited_scans = 0;         // ScanBegins that waited for another connection's scan
  std::uint64_t refused_scans = 0;        // ScanBegins refused by the limits
  std::uint64_t ignored_frames = 0;       // faults from a connection that is not the scanner
  std::uint64_t held_for_queue = 0;       // times a frame waited for can_deliver()
  std::uint64_t bytes = 0;
  std::uint64_t frames = 0;
  std::uint64_t heartbeats_sent = 0;
  std::uint64_t sequence_gaps = 0;
  std::uint64_t scan_errors = 0;  // exceptions that escaped the scan callback
  std::string last_error;
  std::string last_scan_error;
};

class StreamServer {
 public:
  StreamServer(StreamServerOptions options, ScanAssembler::Callback on_scan);
  ~StreamServer();
  StreamServer(const StreamServer&) = delete;
  StreamServer& operator=(const StreamServer&) = delete;

  // Binds and listens (throws fs::Error naming the address on failure).
  void start();
  std::uint16_t port() const { return port_; }
  // Handles socket events for up to timeout_ms; returns false once stop() was called.
  bool poll_once(int timeout_ms);
  // poll_once() until stop().
  void run();
  void stop();  // thread-safe
  void wake();  // thread-safe: ends a poll_once() wait early (e.g. the consumer has room again)
  // Shutdown: stops listening, closes every connection and delivers a scan in progress as partial (even
  // when can_deliver() says no: the consumer takes this last one).
  void close_all();

  // A connection is open (the scanner's or another).
  bool connected() const { return !conns_.empty(); }
  bool scanner_connected() const { return owner_ != 0; }
  std::size_t connection_count() const { return conns_.size(); }
  // The current (or last) scanner's address, "ADDR:PORT".
  const std::string& peer() const { return peer_; }
  const StreamServerStats& stats() const { return stats_; }
  const AssemblerStats& assembler_stats() const { return assembler_.stats(); }
  // The scan in progress, or the last one delivered (for status displays: its header and counts; after a
  // large scan its storage may have been released, see release_large_scans).
  const Scan& current_scan() const { return assembler_.current(); }

 private:
  struct Conn;
  enum class Step { Applied, Held };
  std::int64_t now() const;
  bool ready() const { return !opt_.can_deliver || opt_.can_deliver(); }
  void accept_clients();
  void service(Conn& c);
  Step apply(Conn& c);
  void take_over(Conn& c, const char* why);
  void forward(const Conn& c);  // on_scan_frame for message_
  void drop(Conn& c, bool timeout, ScanStatus why = ScanStatus::Disconnected);
  void deliver(const ScanAssembler::Callback& on_scan, const Scan& scan);
  void send_heartbeat(Conn& c);
  void check_timers();
  void notice(const std::string& peer, const std::string& what) const;
  Conn* find(std::uint64_t id);

  StreamServerOptions opt_;
  ScanAssembler assembler_;
  wire::DecodedMessage message_;
  std::vector<std::uint8_t> tx_;
  std::vector<std::unique_ptr<Conn>> conns_;
  int listen_fd_ = -1;
  bool started_ = false;
  int wake_[2] = {-1, -1};
  std::uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  std::int64_t disconnected_at_ns_ = -1;
  std::uint64_t hb_counter_ = 0, next_id_ = 1;
  std::uint64_t owner_ = 0;        // the connection streaming the scan in progress (0: none connected)
  std::uint64_t gaps_closed_ = 0;  // sequence gaps of closed connections
  bool protocol_cut_ = false;      // the scan in progress lost its connection to a protocol error
  std::string peer_;
  StreamServerStats stats_;
};

// A delivered scan (a copy) or a refused ScanBegin, on its way from the stream server's thread to the thread
// that processes it.
struct ScanJob {
  std::unique_ptr<Scan> scan;  // null for a refused ScanBegin
  msg::ScanBegin refused_begin;
  std::string refusal;  // why the ScanBegin was refused (empty for a scan)
  std::string peer;
  std::uint64_t bytes = 0;   // memory the copy holds (approximately)
  std::uint64_t stream = 0;  // the gateway's stream of this scan (serve --nats --stream); 0: none
};

// Memory a copy of `scan` holds (its slots and stored stripe points).
std::uint64_t scan_copy_bytes(const Scan& scan);

// A bounded hand-off of ScanJobs between two threads. Bounded by a number of jobs and by their bytes; an
// empty queue always takes one job (a scan the limits let in is never refused for its size). push() never
// blocks: the producer asks has_room() first (the stream server's can_deliver), and at shutdown pushes the
// last partial scan regardless.
class ScanQueue {
 public:
  ScanQueue(std::size_t max_jobs, std::uint64_t max_bytes) : max_jobs_(max_jobs), max_bytes_(max_bytes) {}
  bool has_room() const;
  void push(ScanJob job);
  // Blocks until a job is there (true) or the queue is closed and empty (false).
  bool pop(ScanJob& out);
  void close();
  std::size_t size() const;
  std::uint64_t bytes() const;
  std::size_t max_jobs() const { return max_jobs_; }
  std::uint64_t max_bytes() const { return max_bytes_; }

 private:
  const std::size_t max_jobs_;
  const std::uint64_t max_bytes_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<ScanJob> jobs_;
  std::uint64_t bytes_ = 0;
  bool closed_ = false;
};

// "ADDR:PORT" (ADDR may be a name, an IPv4 address or [IPv6]) -> host, port (0 allowed).
void parse_listen_address(const std::string& spec, std::string& host, std::uint16_t& port);

}  // namespace fs::host
