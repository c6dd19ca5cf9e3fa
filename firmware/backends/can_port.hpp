#pragma once
// A non-blocking file descriptor carrying struct can_frame: a SocketCAN raw socket bound to an interface, or
// one end of an AF_UNIX/SOCK_SEQPACKET socketpair (tests, hw-sim). Fixed transmit queue, no allocation.
#include <linux/can.h>

#include <array>
#include <cstdint>
#include <span>
#include <string>

#include "firmware/device/clock.hpp"

namespace fs::fw {

class CanPort {
 public:
  // Takes ownership of fd (closed in the destructor when owns) and makes it non-blocking.
  explicit CanPort(int fd, bool owns = true);
  // Raw CAN socket on `iface` receiving only `filters`, all controller error frames (CAN_RAW_ERR_FILTER), and
  // software receive timestamps (SO_TIMESTAMPING). Throws fs::Error naming the interface and the failed call.
  static CanPort open_raw(const std::string& iface, std::span<const can_filter> filters);
  // A connected SOCK_SEQPACKET pair: [0] for the master, [1] for the twin. Throws fs::Error.
  static std::array<int, 2> socketpair_fds();

  CanPort(CanPort&& o) noexcept;
  CanPort& operator=(CanPort&&) = delete;
  CanPort(const CanPort&) = delete;
  ~CanPort();

  // Queues a frame and tries to write the queue. False when the queue is full (frame dropped, counted).
  bool send(const can_frame& f);
  // Writes as much of the queue as the socket accepts (EAGAIN/ENOBUFS keep the rest queued).
  void flush();
  void drop_queue() { head_ = tail_ = 0; }
  bool tx_pending() const { return head_ != tail_; }
  // Reads one frame. False when none is pending. kernel_ts = receive time on CLOCK_MONOTONIC from the
  // socket's timestamp, or 0 when the fd gives none (socketpair).
  bool recv(can_frame& f, Nanos& kernel_ts);

  int fd() const { return fd_; }
  std::uint64_t tx_dropped() const { return tx_dropped_; }
  std::uint64_t tx_errors() const { return tx_errors_; }
  std::uint64_t rx_errors() const { return rx_errors_; }

 private:
  static constexpr std::size_t kQueue = 64;
  int fd_ = -1;
  bool owns_ = true;
  std::array<can_frame, kQueue> queue_{};
  std::size_t head_ = 0, tail_ = 0;
  std::uint64_t tx_dropped_ = 0, tx_errors_ = 0, rx_errors_ = 0;
};

}  // namespace fs::fw
