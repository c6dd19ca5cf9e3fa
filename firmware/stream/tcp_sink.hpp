#pragma once
// The TCP stream to the host: a wire::FrameSink (the QueuedPublisher's output thread writes whole frames)
// and a LinkState (the controller's interlock can require the host).
//
// A service thread connects to HOST:PORT, reconnecting with exponential backoff (backoff_min doubling up to
// backoff_max) whenever the connection fails or drops. Frames are queued in a bounded buffer (buffer_bytes)
// and sent from there; while disconnected they accumulate; when the buffer is full a new frame is dropped
// and counted (stripe frames in frames_dropped(), reported in ScanEnd.stripes_dropped; never silent). A frame
// cut by a dropped connection is sent again whole on the next one. Host -> scanner heartbeats (wire
// Heartbeat frames) are read on the same socket; with host_heartbeat_timeout > 0 a silent host is treated as
// a lost connection (closed and reconnected).
//
// Delivery accounting: a stripe counts as delivered once the host's TCP stack has acknowledged its last byte
// (the socket's unacknowledged send queue, SIOCOUTQ, no longer covers it). Stripes that never get there
// (never connected, connection refused, name not resolved, a host that stops reading, buffer overflow, still
// queued at the end, lost in flight on a dropped connection) are undelivered; last_error() names the last
// link error (resolution: the getaddrinfo message naming the host; connect / send: strerror naming
// HOST:PORT).
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "common/wire.hpp"
#include "firmware/device/clock.hpp"
#include "firmware/stream/queued_publisher.hpp"

namespace fs::fw {

struct TcpSinkConfig {
  std::size_t buffer_bytes = 16u << 20;
  Nanos backoff_min = 100'000'000;
  Nanos backoff_max = 5'000'000'000;
  Nanos connect_timeout = 1'000'000'000;
  Nanos host_heartbeat_timeout = 0;  // 0: not required
  // The clock that times the host's heartbeats (nullptr: the monotonic clock). Tests inject one, so that a
  // late thread on a loaded machine does not look like a silent host.
  Clock* heartbeat_clock = nullptr;
};

// Name resolution of HOST:PORT once (the start-up check): "" when it resolves, else the error
// ("cannot resolve host 'H': <gai_strerror>").
std::string resolve_error(const std::string& host, std::uint16_t port);

// "HOST:PORT" -> host, port; throws fs::Error naming the spec.
void parse_host_port(const std::string& spec, std::string& host, std::uint16_t& port);

class TcpSink final : public wire::FrameSink, public LinkState {
 public:
  TcpSink(const std::string& host_port, TcpSinkConfig cfg = {});
  ~TcpSink() override;
  TcpSink(const TcpSink&) = delete;
  TcpSink& operator=(const TcpSink&) = delete;

  void write(std::span<const std::uint8_t> frame) override;
  bool connected() const override { return connected_.load(); }
  // Stripes lost so far: buffer overflow + lost in flight on dropped connections.
  std::uint32_t frames_dropped() const override { return stripes_dropped_.load() + lost_in_flight_.load(); }
  std::uint32_t other_frames_dropped() const { return other_dropped_.load(); }
  std::uint32_t connections() const { return connections_.load(); }
  std::uint64_t host_heartbeats() const { return host_heartbeats_.load(); }
  std::size_t buffered_bytes() const;
  // Waits until the buffer is empty and every sent stripe acknowledged by the host, or the timeout passes.
  // True when drained.
  bool drain(Nanos timeout);
  // Stops the service thread and closes the connection after a last look at what the host acknowledged; the
  // delivery counters are final afterwards. Idempotent (the destructor calls it).
  void close();

  // Stripe frames given to write() / acknowledged by the host / lost in flight on a dropped connection.
  std::uint32_t stripes_written() const { return stripes_written_.load(); }
  std::uint32_t stripes_delivered() const { return stripes_delivered_.load(); }
  std::uint32_t stripes_lost_in_flight() const { return lost_in_flight_.load(); }
  // The last link error ("" when none happened), e.g. "cannot connect to 127.0.0.1:1: Connection refused".
  std::string last_error() const;
  const std::string& host() const { return host_; }
  std::uint16_t port() const { return port_; }

 private:
  struct Queued {
    std::size_t size;
    bool stripe;
  };
  void service();
  bool try_connect();
  // Connection lost: the stripes sent but not acknowledged are counted lost; `why` becomes last_error().
  void disconnect(const std::string& why);
  void set_error(std::string e);
  // Moves acknowledged stripes from in_flight_ to the delivered count (mu_ held).
  void account_acks_locked();

  std::string host_;
  std::uint16_t port_ = 0;
  TcpSinkConfig cfg_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::vector<std::uint8_t> buf_;        // queued frames, back to back
  std::deque<Queued> sizes_;             // their sizes, stripe or not
  std::size_t head_ = 0;                 // start of the first frame in buf_
  std::size_t sent_ = 0;                 // bytes of the first frame already sent on this connection
  std::uint64_t conn_bytes_ = 0;         // bytes sent on this connection
  std::deque<std::uint64_t> in_flight_;  // end offsets (conn_bytes_) of stripes sent, not yet acknowledged
  std::string last_error_;
  int fd_ = -1;
  bool closed_ = false;
  std::atomic<bool> stop_{false}, connected_{false};
  std::atomic<std::uint32_t> stripes_dropped_{0}, other_dropped_{0}, connections_{0};
  std::atomic<std::uint32_t> stripes_written_{0}, stripes_delivered_{0}, lost_in_flight_{0};
  std::atomic<std::uint64_t> host_heartbeats_{0};
  Nanos last_host_heartbeat_ = 0;
  std::thread thread_;
};

}  // namespace fs::fw
