#include "firmware/backends/can_port.hpp"

#include <fcntl.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <linux/errqueue.h>
#include <linux/net_tstamp.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <utility>

#include "common/error.hpp"

namespace fs::fw {
namespace {

Error sys_error(const std::string& what) { return Error(what + ": " + std::strerror(errno)); }

void set_nonblocking(int fd) {
  int fl = ::fcntl(fd, F_GETFL);
  if (fl < 0 || ::fcntl(fd, F_SETFL, fl | O_NONBLOCK) < 0) throw sys_error("fcntl(O_NONBLOCK)");
}

Nanos ts_ns(const timespec& t) { return Nanos(t.tv_sec) * 1'000'000'000 + t.tv_nsec; }

}  // namespace

CanPort::CanPort(int fd, bool owns) : fd_(fd), owns_(owns) {
  if (fd_ < 0) throw Error("CanPort: invalid file descriptor");
  set_nonblocking(fd_);
}

CanPort::CanPort(CanPort&& o) noexcept
    : fd_(std::exchange(o.fd_, -1)),
      owns_(o.owns_),
      queue_(o.queue_),
      head_(o.head_),
      tail_(o.tail_),
      tx_dropped_(o.tx_dropped_),
      tx_errors_(o.tx_errors_),
      rx_errors_(o.rx_errors_) {}

CanPort::~CanPort() {
  if (owns_ && fd_ >= 0) ::close(fd_);
}

CanPort CanPort::open_raw(const std::string& iface, std::span<const can_filter> filters) {
  const std::string where = "CAN interface '" + iface + "'";
  if (iface.empty() || iface.size() >= IFNAMSIZ) throw Error(where + ": bad interface name");
  int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) throw sys_error(where + ": socket(PF_CAN, SOCK_RAW, CAN_RAW)");
  CanPort port(fd, true);
  if (!filters.empty() &&
      ::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, filters.data(), socklen_t(filters.size_bytes())) < 0)
    throw sys_error(where + ": setsockopt(CAN_RAW_FILTER)");
  can_err_mask_t err_mask = CAN_ERR_TX_TIMEOUT | CAN_ERR_CRTL | CAN_ERR_BUSOFF | CAN_ERR_BUSERROR |
                            CAN_ERR_RESTARTED | CAN_ERR_ACK | CAN_ERR_PROT;
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) < 0)
    throw sys_error(where + ": setsockopt(CAN_RAW_ERR_FILTER)");
  int ts_flags = SOF_TIMESTAMPING_RX_SOFTWARE | SOF_TIMESTAMPING_SOFTWARE;
  if (::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPING, &ts_flags, sizeof ts_flags) < 0)
    throw sys_error(where + ": setsockopt(SO_TIMESTAMPING)");
  ifreq ifr{};
  std::strncpy(ifr.ifr_name, iface.c_str(), IFNAMSIZ - 1);
  if (::ioctl(fd, SIOCGIFINDEX, &ifr) < 0) throw sys_error(where + ": no such interface (SIOCGIFINDEX)");
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifr.ifr_ifindex;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0) throw sys_error(where + ": bind");
  return port;
}

std::array<int, 2> CanPort::socketpair_fds() {
  int sv[2];
  if (::socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, sv) < 0)
    throw sys_error("socketpair(SEQPACKET)");
  return {sv[0], sv[1]};
}

bool CanPort::send(const can_frame& f) {
  if (tail_ - head_ >= kQueue) {
    ++tx_dropped_;
    flush();
    return false;
  }
  queue_[tail_++ % kQueue] = f;
  flush();
  return true;
}

void CanPort::flush() {
  while (head_ != tail_) {
    const can_frame& f = queue_[head_ % kQueue];
    ssize_t n = ::write(fd_, &f, sizeof f);
    if (n == static_cast<ssize_t>(sizeof f)) {
      ++head_;
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS)) break;  // retry later
    ++tx_errors_;  // ENETDOWN, EPIPE (peer gone), short write: the frame is lost
    ++head_;
  }
  if (head_ == tail_) head_ = tail_ = 0;
}

bool CanPort::recv(can_frame& f, Nanos& kernel_ts) {
  kernel_ts = 0;
  alignas(cmsghdr) char ctrl[CMSG_SPACE(sizeof(timespec) * 3) + CMSG_SPACE(sizeof(timeval))];
  iovec iov{&f, sizeof f};
  msghdr msg{};
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  msg.msg_control = ctrl;
  msg.msg_controllen = sizeof ctrl;
  for (;;) {
    ssize_t n = ::recvmsg(fd_, &msg, MSG_DONTWAIT);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno != EAGAIN && errno != EWOULDBLOCK) ++rx_errors_;
      return false;
    }
    if (n == 0) return false;  // peer closed (socketpair)
    if (n != static_cast<ssize_t>(sizeof f) && n != static_cast<ssize_t>(CAN_MTU)) {
      ++rx_errors_;  // CAN FD or garbage: not for us
      msg.msg_controllen = sizeof ctrl;
      continue;
    }
    if (f.len > CAN_MAX_DLEN) {
      ++rx_errors_;
      msg.msg_controllen = sizeof ctrl;
      continue;
    }
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c; c = CMSG_NXTHDR(&msg, c)) {
      if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPING) {
        timespec ts[3];
        std::memcpy(ts, CMSG_DATA(c), sizeof ts);
        // Software timestamps are CLOCK_REALTIME: move them onto CLOCK_MONOTONIC (the loop's clock).
        timespec real{}, mono{};
        ::clock_gettime(CLOCK_REALTIME, &real);
        ::clock_gettime(CLOCK_MONOTONIC, &mono);
        if (ts[0].tv_sec != 0 || ts[0].tv_nsec != 0) kernel_ts = ts_ns(ts[0]) - (ts_ns(real) - ts_ns(mono));
      }
    }
    return true;
  }
}

}  // namespace fs::fw
