#include "firmware/backends/v4l2_device.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

namespace fs::fw {
namespace {

class SystemV4l2Io final : public V4l2Io {
 public:
  int open(const char* path, int flags) override { return ::open(path, flags); }
  int close(int fd) override { return ::close(fd); }
  int ioctl(int fd, unsigned long request, void* arg) override { return ::ioctl(fd, request, arg); }
  void* mmap(std::size_t length, int fd, off_t offset) override {
    return ::mmap(nullptr, length, PROT_READ | PROT_WRITE, MAP_SHARED, fd, offset);
  }
  int munmap(void* addr, std::size_t length) override { return ::munmap(addr, length); }
  int poll_in(int fd, int timeout_ms) override {
    pollfd p{fd, POLLIN, 0};
    return ::poll(&p, 1, timeout_ms);
  }
};

}  // namespace

V4l2Io& system_v4l2_io() {
  static SystemV4l2Io io;
  return io;
}

}  // namespace fs::fw
