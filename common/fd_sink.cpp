#include "common/fd_sink.hpp"

#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace fs::wire {

namespace {
bool fd_is_socket(int fd) {
  struct stat st {};
  return ::fstat(fd, &st) == 0 && S_ISSOCK(st.st_mode);
}
}  // namespace

FdSink::FdSink(int fd, std::string name) : fd_(fd), name_(std::move(name)), is_socket_(fd_is_socket(fd)) {
  if (fd < 0) throw Error(name_ + ": invalid file descriptor " + std::to_string(fd));
}

void FdSink::write(std::span<const std::uint8_t> bytes) {
  const std::uint8_t* p = bytes.data();
  std::size_t left = bytes.size();
  while (left > 0) {
    const ssize_t n = is_socket_ ? ::send(fd_, p, left, MSG_NOSIGNAL) : ::write(fd_, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw error_at_offset(name_, written_, std::string("write failed: ") + std::strerror(errno));
    }
    if (n == 0) throw error_at_offset(name_, written_, "write returned 0 (peer gone?)");
    p += n;
    left -= static_cast<std::size_t>(n);
    written_ += static_cast<std::uint64_t>(n);
  }
}

}  // namespace fs::wire
