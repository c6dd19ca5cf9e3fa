#include "host/io/stream_server.hpp"

#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "common/error.hpp"
#include "common/host_port.hpp"
#include "common/monotonic_time.hpp"

namespace fs::host {

void parse_listen_address(const std::string& spec, std::string& host, std::uint16_t& port) {
  split_host_port(spec, "listen address", "ADDR:PORT (e.g. 127.0.0.1:5555)", 0, host, port);
}

StreamServer::StreamServer(StreamServerOptions options, ScanAssembler::Callback on_scan)
    : opt_(std::move(options)),
      assembler_([this, cb = std::move(on_scan)](const Scan& scan) { deliver(cb, scan); }, opt_.limits),
      decoder_("tcp " + opt_.listen),
      rx_(64 * 1024),
      tx_(wire::kFrameOverhead + wire::kHeartbeatSize + 16) {
  if (::pipe2(wake_, O_NONBLOCK | O_CLOEXEC) != 0)
    throw Error(std::string("stream server: pipe: ") + std::strerror(errno));
}

StreamServer::~StreamServer() {
  if (client_ >= 0) ::close(client_);
  if (listen_fd_ >= 0) ::close(listen_fd_);
  for (int fd : wake_)
    if (fd >= 0) ::close(fd);
}

std::int64_t StreamServer::now() const {
  if (opt_.now_ns) return opt_.now_ns();
  return monotonic_ns();
}

void StreamServer::deliver(const ScanAssembler::Callback& on_scan, const Scan& scan) {
  protocol_cut_ = false;
  if (!on_scan) return;
  // Processing a scan is not the stream's business: what escapes is counted, never a protocol error.
  try {
    on_scan(scan);
  } catch (const std::exception& e) {
    ++stats_.scan_errors;
    stats_.last_scan_error = "scan " + std::to_string(scan.scan_id()) + ": " + e.what();
  }
}

void StreamServer::on_frame() {
  // A scan cut by a protocol error and not resumed (a new ScanBegin instead) ends as such, not superseded.
  if (protocol_cut_ && message_.type == msg::Type::ScanBegin)
    assembler_.end_of_stream(ScanStatus::ProtocolError);
  if (message_.type != msg::Type::Heartbeat) protocol_cut_ = false;
  assembler_.on_message(message_);
}

void StreamServer::start() {
  std::string host;
  std::uint16_t port = 0;
  parse_listen_address(opt_.listen, host, port);
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE;
  addrinfo* res = nullptr;
  const std::string port_s = std::to_string(port);
  if (const int rc = ::getaddrinfo(host.c_str(), port_s.c_str(), &hints, &res); rc != 0)
    throw Error("listen address '" + opt_.listen + "': " + ::gai_strerror(rc));
  std::string err = "no address";
  for (addrinfo* ai = res; ai; ai = ai->ai_next) {
    const int fd = ::socket(ai->ai_family, ai->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, ai->ai_protocol);
    if (fd < 0) {
      err = std::strerror(errno);
      continue;
    }
    const int one = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
    if (::bind(fd, ai->ai_addr, ai->ai_addrlen) != 0 || ::listen(fd, 4) != 0) {
      err = std::strerror(errno);
      ::close(fd);
      continue;
    }
    sockaddr_storage ss{};
    socklen_t len = sizeof(ss);
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&ss), &len);
    port_ = ntohs(ss.ss_family == AF_INET6 ? reinterpret_cast<sockaddr_in6*>(&ss)->sin6_port
                                           : reinterpret_cast<sockaddr_in*>(&ss)->sin_port);
    listen_fd_ = fd;
    break;
  }
  ::freeaddrinfo(res);
  if (listen_fd_ < 0) throw Error("listen address '" + opt_.listen + "': cannot listen: " + err);
}

void StreamServer::stop() {
  stop_ = true;
  const char c = 1;
  [[maybe_unused]] const ssize_t n = ::write(wake_[1], &c, 1);
}

void StreamServer::run() {
  while (poll_once(100)) {
  }
}

bool StreamServer::poll_once(int timeout_ms) {
  if (stop_) return false;
  if (listen_fd_ < 0) throw Error("stream server: poll before start()");
  pollfd fds[3] = {{wake_[0], POLLIN, 0}, {listen_fd_, POLLIN, 0}, {client_, POLLIN, 0}};
  const int n = ::poll(fds, client_ >= 0 ? 3 : 2, timeout_ms);
  if (n < 0 && errno != EINTR) throw Error(std::string("stream server: poll: ") + std::strerror(errno));
  if (n > 0) {
    if (fds[0].revents) {
      char buf[16];
      while (::read(wake_[0], buf, sizeof(buf)) > 0) {
      }
    }
    if (fds[1].revents & POLLIN) accept_client();
    if (client_ >= 0 && fds[2].fd == client_ && (fds[2].revents & (POLLIN | POLLHUP | POLLERR)))
      read_client();
  }
  check_timers();
  return !stop_;
}

void StreamServer::accept_client() {
  sockaddr_storage ss{};
  socklen_t len = sizeof(ss);
  const int fd = ::accept4(listen_fd_, reinterpret_cast<sockaddr*>(&ss), &len, SOCK_NONBLOCK | SOCK_CLOEXEC);
  if (fd < 0) return;                    // EAGAIN / ECONNABORTED: nothing to do
  if (client_ >= 0) drop_client(false);  // the scanner re-dialled: the new connection wins
  char host[NI_MAXHOST] = "?", serv[NI_MAXSERV] = "?";
  ::getnameinfo(reinterpret_cast<sockaddr*>(&ss), len, host, sizeof(host), serv, sizeof(serv),
                NI_NUMERICHOST | NI_NUMERICSERV);
  peer_ = ss.ss_family == AF_INET6 ? "[" + std::string(host) + "]:" + serv : std::string(host) + ":" + serv;
  const int one = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
  client_ = fd;
  ++stats_.connections;
  decoder_.reset(0);  // a frame cut by the old connection is resent whole by the scanner
  last_rx_ns_ = now();
  disconnected_at_ns_ = -1;
  send_heartbeat();
}

void StreamServer::read_client() {
  for (;;) {
    const ssize_t r = ::recv(client_, rx_.data(), rx_.size(), MSG_DONTWAIT);
    if (r == 0) {
      drop_client(false);
      return;
    }
    if (r < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK) return;
      if (errno == EINTR) continue;
      stats_.last_error = std::string("recv: ") + std::strerror(errno);
      drop_client(false);
      return;
    }
    stats_.bytes += static_cast<std::uint64_t>(r);
    last_rx_ns_ = now();
    std::span<const std::uint8_t> in(rx_.data(), static_cast<std::size_t>(r));
    try {
      while (!in.empty()) {
        in = in.subspan(decoder_.feed(in));
        wire::FrameView f;
        while (decoder_.next(f)) {
          ++stats_.frames;
          wire::decode(f, message_, decoder_.source());
          on_frame();
        }
      }
    } catch (const Error& e) {
      ++stats_.protocol_errors;
      stats_.last_error = "protocol error from " + peer_ + ": " + e.what();
      if (opt_.on_protocol_error) opt_.on_protocol_error(peer_, e.what());
      if (assembler_.in_scan()) protocol_cut_ = true;
      drop_client(false, protocol_cut_ ? ScanStatus::ProtocolError : ScanStatus::Disconnected);
      return;
    }
    stats_.sequence_gaps = decoder_.sequence_gaps();
  }
}

void StreamServer::drop_client(bool timeout, ScanStatus why) {
  if (client_ < 0) return;
  ::close(client_);
  client_ = -1;
  if (timeout)
    ++stats_.link_timeouts;
  else
    ++stats_.disconnects;
  disconnected_at_ns_ = now();
  if (opt_.reconnect_grace_ms <= 0) assembler_.end_of_stream(why);
}

void StreamServer::send_heartbeat() {
  if (client_ < 0) return;
  msg::Heartbeat hb;
  hb.time_ns = now();
  hb.counter = ++hb_counter_;
  hb.state = 0;
  const std::size_t n = wire::encode(tx_, tx_seq_++, hb);
  // Best effort: a full socket buffer just skips this heartbeat.
  if (::send(client_, tx_.data(), n, MSG_DONTWAIT | MSG_NOSIGNAL) == static_cast<ssize_t>(n))
    ++stats_.heartbeats_sent;
  last_hb_ns_ = now();
}

void StreamServer::check_timers() {
  const std::int64_t t = now();
  if (client_ >= 0) {
    if (opt_.link_timeout_ms > 0 && t - last_rx_ns_ > opt_.link_timeout_ms * 1'000'000) {
      stats_.last_error =
          "link timeout: nothing received for " + std::to_string(opt_.link_timeout_ms) + " ms";
      drop_client(true);
    } else if (opt_.heartbeat_interval_ms > 0 && t - last_hb_ns_ >= opt_.heartbeat_interval_ms * 1'000'000) {
      send_heartbeat();
    }
  }
  if (client_ < 0 && disconnected_at_ns_ >= 0 && assembler_.in_scan() &&
      t - disconnected_at_ns_ >= opt_.reconnect_grace_ms * 1'000'000) {
    assembler_.end_of_stream(protocol_cut_ ? ScanStatus::ProtocolError : ScanStatus::Disconnected);
    disconnected_at_ns_ = -1;
  }
}

void StreamServer::close_all() {
  if (client_ >= 0) {
    ::close(client_);
    client_ = -1;
  }
  assembler_.end_of_stream(protocol_cut_ ? ScanStatus::ProtocolError : ScanStatus::Disconnected);
  disconnected_at_ns_ = -1;
}

}  // namespace fs::host
