#include "firmware/stream/tcp_sink.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <linux/sockios.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>

#include "common/error.hpp"
#include "common/host_port.hpp"
#include "common/monotonic_time.hpp"

namespace fs::fw {

namespace {
Nanos mono_now() { return monotonic_ns(); }
Nanos heartbeat_now(const TcpSinkConfig& c) {
  return c.heartbeat_clock ? c.heartbeat_clock->now() : mono_now();
}

std::string gai_message(int rc) {
  return rc == EAI_SYSTEM ? std::string(std::strerror(errno)) : std::string(gai_strerror(rc));
}

// Bytes sent on fd that the peer has not acknowledged yet (-1 when unknown).
long unacked_bytes(int fd) {
  int n = 0;
  if (fd < 0 || ioctl(fd, SIOCOUTQ, &n) != 0) return -1;
  return n;
}
}  // namespace

std::string resolve_error(const std::string& host, std::uint16_t port) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* res = nullptr;
  const int rc = getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &res);
  if (res) freeaddrinfo(res);
  if (rc == 0) return {};
  return "cannot resolve host '" + host + "': " + gai_message(rc);
}

void parse_host_port(const std::string& spec, std::string& host, std::uint16_t& port) {
  split_host_port(spec, "stream address", "HOST:PORT", 1, host, port);
}

TcpSink::TcpSink(const std::string& host_port, TcpSinkConfig cfg) : cfg_(cfg) {
  parse_host_port(host_port, host_, port_);
  buf_.reserve(cfg_.buffer_bytes);
  thread_ = std::thread([this] { service(); });
}

TcpSink::~TcpSink() { close(); }

void TcpSink::close() {
  stop_ = true;
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  std::lock_guard<std::mutex> lock(mu_);
  if (closed_) return;
  closed_ = true;
  account_acks_locked();
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  connected_ = false;
}

std::string TcpSink::last_error() const {
  std::lock_guard<std::mutex> lock(mu_);
  return last_error_;
}

void TcpSink::set_error(std::string e) {
  std::lock_guard<std::mutex> lock(mu_);
  last_error_ = std::move(e);
}

void TcpSink::account_acks_locked() {
  if (in_flight_.empty()) return;
  const long unacked = unacked_bytes(fd_);
  if (unacked < 0) return;
  const std::uint64_t acked = conn_bytes_ - static_cast<std::uint64_t>(unacked);
  while (!in_flight_.empty() && in_flight_.front() <= acked) {
    in_flight_.pop_front();
    stripes_delivered_.fetch_add(1);
  }
}

std::size_t TcpSink::buffered_bytes() const {
  std::lock_guard<std::mutex> lock(mu_);
  return buf_.size() - head_;
}

void TcpSink::write(std::span<const std::uint8_t> frame) {
  const bool stripe = frame.size() > 6 && frame[6] == static_cast<std::uint8_t>(msg::Type::Stripe);
  if (stripe) stripes_written_.fetch_add(1);
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (buf_.size() - head_ + frame.size() > cfg_.buffer_bytes) {
      (stripe ? stripes_dropped_ : other_dropped_).fetch_add(1);
      return;
    }
    if (buf_.size() + frame.size() > buf_.capacity()) {  // compact (no reallocation: capacity is the bound)
      buf_.erase(buf_.begin(), buf_.begin() + static_cast<std::ptrdiff_t>(head_));
      head_ = 0;
    }
    buf_.insert(buf_.end(), frame.begin(), frame.end());
    sizes_.push_back(Queued{frame.size(), stripe});
  }
  cv_.notify_one();
}

bool TcpSink::drain(Nanos timeout) {
  const Nanos end = mono_now() + timeout;
  const auto drained = [this] {
    std::lock_guard<std::mutex> lock(mu_);
    // Connected or not: nothing queued and nothing unacknowledged in flight means all was delivered.
    if (buf_.size() != head_) return false;
    account_acks_locked();
    return in_flight_.empty();
  };
  while (mono_now() < end) {
    if (drained()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return drained();
}

bool TcpSink::try_connect() {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* res = nullptr;
  const std::string port = std::to_string(port_);
  const std::string where = host_ + ":" + port;
  const int grc = getaddrinfo(host_.c_str(), port.c_str(), &hints, &res);
  if (grc != 0 || !res) {
    set_error("cannot resolve host '" + host_ + "': " + (grc != 0 ? gai_message(grc) : "no address"));
    if (res) freeaddrinfo(res);
    return false;
  }
  int fd = -1;
  std::string why = "no usable address";
  for (addrinfo* a = res; a && fd < 0; a = a->ai_next) {
    fd = socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) {
      why = std::strerror(errno);
      continue;
    }
    int rc = connect(fd, a->ai_addr, a->ai_addrlen);
    int err = rc == 0 ? 0 : errno;
    if (rc != 0 && err == EINPROGRESS) {
      pollfd p{fd, POLLOUT, 0};
      const int ms = static_cast<int>(cfg_.connect_timeout / 1'000'000);
      rc = poll(&p, 1, ms) == 1 ? 0 : -1;
      err = rc == 0 ? 0 : ETIMEDOUT;
      socklen_t len = sizeof err;
      if (rc == 0 && (getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len) != 0 || err != 0)) rc = -1;
    }
    if (rc != 0) {
      why = std::strerror(err);
      ::close(fd);
      fd = -1;
    }
  }
  freeaddrinfo(res);
  if (fd < 0) {
    set_error("cannot connect to " + where + ": " + why);
    return false;
  }
  int one = 1;
  setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  std::lock_guard<std::mutex> lock(mu_);
  fd_ = fd;
  sent_ = 0;  // a frame cut by the previous connection goes again whole
  conn_bytes_ = 0;
  last_host_heartbeat_ = heartbeat_now(cfg_);
  connected_ = true;
  connections_.fetch_add(1);
  return true;
}

void TcpSink::disconnect(const std::string& why) {
  std::lock_guard<std::mutex> lock(mu_);
  account_acks_locked();
  // Sent on this connection but never acknowledged: gone with it (only a frame cut mid-send is resent).
  lost_in_flight_.fetch_add(static_cast<std::uint32_t>(in_flight_.size()));
  in_flight_.clear();
  last_error_ = "connection to " + host_ + ":" + std::to_string(port_) + " lost: " + why;
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  sent_ = 0;
  connected_ = false;
}

void TcpSink::service() {
  Nanos backoff = cfg_.backoff_min;
  wire::FrameDecoder dec("host " + host_ + ":" + std::to_string(port_));
  std::vector<std::uint8_t> rx(4096);
  while (!stop_.load()) {
    if (!connected_.load()) {
      if (try_connect()) {
        backoff = cfg_.backoff_min;
        dec.reset();
        continue;
      }
      std::unique_lock<std::mutex> lock(mu_);
      cv_.wait_for(lock, std::chrono::nanoseconds(backoff), [this] { return stop_.load(); });
      backoff = std::min(backoff * 2, cfg_.backoff_max);
      continue;
    }
    bool want_out;
    int fd;
    {
      std::lock_guard<std::mutex> lock(mu_);
      want_out = !sizes_.empty();
      fd = fd_;
    }
    pollfd p{fd, static_cast<short>(POLLIN | (want_out ? POLLOUT : 0)), 0};
    const int n = poll(&p, 1, 10);
    if (n < 0 && errno != EINTR) {
      disconnect(std::strerror(errno));
      continue;
    }
    std::string why;
    bool lost = (p.revents & (POLLERR | POLLHUP | POLLNVAL)) != 0;
    if (lost) {
      int err = 0;
      socklen_t len = sizeof err;
      why = getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len) == 0 && err != 0 ? std::strerror(err)
                                                                              : "closed by the host";
    }
    if (!lost && (p.revents & POLLIN)) {
      const ssize_t r = recv(fd, rx.data(), rx.size(), MSG_DONTWAIT);
      if (r == 0 || (r < 0 && errno != EAGAIN && errno != EINTR)) {
        lost = true;
        why = r == 0 ? "closed by the host" : std::strerror(errno);
      } else if (r > 0) {
        std::span<const std::uint8_t> in(rx.data(), static_cast<std::size_t>(r));
        try {
          while (!in.empty()) {
            in = in.subspan(dec.feed(in));
            wire::FrameView f;
            while (dec.next(f)) {
              if (f.header.type == msg::Type::Heartbeat) {
                host_heartbeats_.fetch_add(1);
                std::lock_guard<std::mutex> lock(mu_);
                last_host_heartbeat_ = heartbeat_now(cfg_);
              }
            }
          }
        } catch (const Error&) {
          dec.reset();  // garbage from the host: ignore it
        }
      }
    }
    if (!lost && (p.revents & POLLOUT)) {
      std::lock_guard<std::mutex> lock(mu_);
      while (!sizes_.empty()) {
        const std::size_t len = sizes_.front().size - sent_;
        const ssize_t w = send(fd_, buf_.data() + head_ + sent_, len, MSG_NOSIGNAL | MSG_DONTWAIT);
        if (w < 0) {
          if (errno != EAGAIN && errno != EINTR) {
            lost = true;
            why = std::strerror(errno);
          }
          break;
        }
        sent_ += static_cast<std::size_t>(w);
        conn_bytes_ += static_cast<std::uint64_t>(w);
        if (sent_ < sizes_.front().size) break;
        if (sizes_.front().stripe) in_flight_.push_back(conn_bytes_);
        head_ += sizes_.front().size;
        sizes_.pop_front();
        sent_ = 0;
        if (sizes_.empty()) {
          buf_.clear();
          head_ = 0;
        }
      }
    }
    if (!lost && cfg_.host_heartbeat_timeout > 0) {
      std::lock_guard<std::mutex> lock(mu_);
      lost = heartbeat_now(cfg_) - last_host_heartbeat_ > cfg_.host_heartbeat_timeout;
      if (lost)
        why = "no heartbeat from the host for " + std::to_string(cfg_.host_heartbeat_timeout / 1'000'000) +
              " ms";
    }
    if (!lost) {
      std::lock_guard<std::mutex> lock(mu_);
      account_acks_locked();
    }
    if (lost) disconnect(why);
  }
}

}  // namespace fs::fw
