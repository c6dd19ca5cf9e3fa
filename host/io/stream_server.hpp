#pragma once
// The host end of the live scanner stream: listens on ADDR:PORT (127.0.0.1 by default), accepts the
// scanner's connection (the firmware connects out, see firmware/stream/tcp_sink.hpp), decodes frames
// incrementally and assembles scans, delivered through the callback as they end.
//
// Link handling:
//  * The host sends a Heartbeat frame every heartbeat_interval_ms (the scanner may require them).
//  * A connection silent for link_timeout_ms (no frame, not even a scanner heartbeat) is closed.
//  * A closed / lost connection leaves the scan in progress open for reconnect_grace_ms: the scanner
//    reconnects and resends what it buffered, and the scan continues (possibly to completion). When the grace
//    expires, the scan is delivered as partial (ScanStatus::Disconnected). grace 0 = deliver at once.
//  * A new connection replaces the current one (a scanner that rebooted / re-dialled).
//  * A malformed frame (bad CRC, unknown version, absurd length) closes the connection (protocol error,
//    counted, last_error names the peer, on_protocol_error is told); the scanner reconnects and resends. A
//    scan cut by it that is not resumed ends as ScanStatus::ProtocolError (not Superseded / Disconnected).
//  * The scan callback handles its own processing errors; an exception escaping it is counted (scan_errors,
//    last_scan_error) and is neither a protocol error nor the end of the connection or of the server.
// One thread: run() or poll_once() in the caller's thread; stop() may be called from any thread.
// The clock is injectable for tests.
#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "common/wire.hpp"
#include "host/io/scan_assembler.hpp"

namespace fs::host {

struct StreamServerOptions {
  std::string listen = "127.0.0.1:5555";  // ADDR:PORT; port 0 picks a free port (see port())
  std::int64_t heartbeat_interval_ms = 500;
  std::int64_t link_timeout_ms = 3000;
  std::int64_t reconnect_grace_ms = 5000;
  ScanLimits limits;
  std::function<std::int64_t()> now_ns;  // monotonic clock; default CLOCK_MONOTONIC
  // Called for every protocol error, before the connection is closed: (peer "ADDR:PORT", reason).
  std::function<void(const std::string& peer, const std::string& reason)> on_protocol_error;
};

struct StreamServerStats {
  std::uint64_t connections = 0;
  std::uint64_t disconnects = 0;      // peer closed or errored
  std::uint64_t link_timeouts = 0;    // closed for silence
  std::uint64_t protocol_errors = 0;  // closed for a malformed frame
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
  // Shutdown: closes the connection and delivers a scan in progress as partial.
  void close_all();

  bool connected() const { return client_ >= 0; }
  // The current (or last) scanner's address, "ADDR:PORT".
  const std::string& peer() const { return peer_; }
  const StreamServerStats& stats() const { return stats_; }
  const AssemblerStats& assembler_stats() const { return assembler_.stats(); }
  // The scan in progress, or the last one delivered (for status displays).
  const Scan& current_scan() const { return assembler_.current(); }

 private:
  std::int64_t now() const;
  void accept_client();
  void read_client();
  void drop_client(bool timeout, ScanStatus why = ScanStatus::Disconnected);
  void deliver(const ScanAssembler::Callback& on_scan, const Scan& scan);
  void on_frame();
  void send_heartbeat();
  void check_timers();

  StreamServerOptions opt_;
  ScanAssembler assembler_;
  wire::FrameDecoder decoder_;
  wire::DecodedMessage message_;
  std::vector<std::uint8_t> rx_;
  std::vector<std::uint8_t> tx_;
  int listen_fd_ = -1, client_ = -1;
  int wake_[2] = {-1, -1};
  std::uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  std::int64_t last_rx_ns_ = 0, last_hb_ns_ = 0, disconnected_at_ns_ = -1;
  std::uint64_t hb_counter_ = 0;
  std::uint32_t tx_seq_ = 0;
  bool protocol_cut_ = false;  // the scan in progress lost its connection to a protocol error
  std::string peer_;
  StreamServerStats stats_;
};

// "ADDR:PORT" (ADDR may be a name, an IPv4 address or [IPv6]) -> host, port (0 allowed).
void parse_listen_address(const std::string& spec, std::string& host, std::uint16_t& port);

}  // namespace fs::host
