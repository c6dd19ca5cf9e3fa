#pragma once
// A wire::FrameSink over a POSIX file descriptor (TCP socket, pipe, file): write() blocks until every byte is
// written (retrying partial writes and EINTR) or throws fs::Error naming the sink and the stream offset.
// Sockets are written with MSG_NOSIGNAL, so a vanished peer is an EPIPE error, not a SIGPIPE.
// The descriptor is not owned.
#include <cstdint>
#include <span>
#include <string>

#include "common/wire.hpp"

namespace fs::wire {

class FdSink final : public FrameSink {
 public:
  FdSink(int fd, std::string name);
  void write(std::span<const std::uint8_t> bytes) override;
  std::uint64_t bytes_written() const { return written_; }
  int fd() const { return fd_; }

 private:
  int fd_;
  std::string name_;
  bool is_socket_;
  std::uint64_t written_ = 0;
};

}  // namespace fs::wire
