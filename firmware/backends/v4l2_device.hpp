#pragma once
// The system calls the V4L2 camera makes, behind a small interface so that tests can put an fd-level fake
// driver underneath (tests/firmware/backends/fake_v4l2.hpp). system_v4l2_io() is the real kernel.
#include <sys/types.h>

#include <cstddef>

namespace fs::fw {

class V4l2Io {
 public:
  virtual ~V4l2Io() = default;
  virtual int open(const char* path, int flags) = 0;  // fd, or -1 with errno
  virtual int close(int fd) = 0;
  virtual int ioctl(int fd, unsigned long request, void* arg) = 0;   // -1 with errno
  virtual void* mmap(std::size_t length, int fd, off_t offset) = 0;  // MAP_FAILED with errno
  virtual int munmap(void* addr, std::size_t length) = 0;
  // Waits up to timeout_ms for the fd to be readable: > 0 ready, 0 timeout, -1 with errno (EINTR possible).
  virtual int poll_in(int fd, int timeout_ms) = 0;
};

V4l2Io& system_v4l2_io();

}  // namespace fs::fw
