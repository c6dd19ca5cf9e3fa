#include "host/io/stream_server.hpp"

#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "common/error.hpp"
#include "common/host_port.hpp"
#include "common/monotonic_time.hpp"

namespace fs::host {

void parse_listen_address(const std::string& spec, std::string& host, std::uint16_t& port) {
  split_host_port(spec, "listen address", "ADDR:PORT (e.g. 127.0.0.1:5555)", 0, host, port);
}

// One open connection: its own decoder, the received bytes not yet fed to it, and the frame popped from it
// but not applied yet (held: a ScanBegin waiting for another scanner's scan, or back-pressure). A connection
// with a held frame is not read: its frame view stays valid as its decoder is left alone.
struct StreamServer::Conn {
  Conn(int fd_, std::uint64_t id_, std::string peer_)
      : fd(fd_), id(id_), peer(std::move(peer_)), decoder("tcp " + peer) {}
  int fd;
  std::uint64_t id;
  std::string peer;
  wire::FrameDecoder decoder;
  std::vector<std::uint8_t> pending;  // received, not yet fed to the decoder
  std::size_t pending_off = 0;
  wire::FrameView frame;
  bool has_frame = false;
  bool waiting = false;  // a held ScanBegin, logged once
  bool closed = false;
  std::uint64_t frames = 0;
  std::int64_t last_rx_ns = 0, last_hb_ns = 0;
  std::uint32_t tx_seq = 0;
};

std::uint64_t scan_copy_bytes(const Scan& scan) {
  return sizeof(Scan) + ScanLimits::scan_storage_bytes(scan.slot_count(), scan.points_stored());
}

StreamServer::StreamServer(StreamServerOptions options, ScanAssembler::Callback on_scan)
    : opt_(std::move(options)),
      assembler_([this, cb = std::move(on_scan)](const Scan& scan) { deliver(cb, scan); }, opt_.limits),
      tx_(wire::kFrameOverhead + wire::kHeartbeatSize + 16) {
  if (opt_.max_clients < 1) throw Error("stream server: max_clients must be at least 1");
  if (::pipe2(wake_, O_NONBLOCK | O_CLOEXEC) != 0)
    throw Error(std::string("stream server: pipe: ") + std::strerror(errno));
}

StreamServer::~StreamServer() {
  for (auto& c : conns_)
    if (!c->closed) ::close(c->fd);
  if (listen_fd_ >= 0) ::close(listen_fd_);
  for (int fd : wake_)
    if (fd >= 0) ::close(fd);
}

std::int64_t StreamServer::now() const {
  if (opt_.now_ns) return opt_.now_ns();
  return monotonic_ns();
}

void StreamServer::notice(const std::string& peer, const std::string& what) const {
  if (opt_.on_notice) opt_.on_notice(peer, what);
}

StreamServer::Conn* StreamServer::find(std::uint64_t id) {
  for (auto& c : conns_)
    if (c->id == id && !c->closed) return c.get();
  return nullptr;
}

void StreamServer::deliver(const ScanAssembler::Callback& on_scan, const Scan& scan) {
  protocol_cut_ = false;
  if (on_scan) {
    // Processing a scan is not the stream's business: what escapes is counted, never a protocol error.
    try {
      on_scan(scan);
    } catch (const std::exception& e) {
      ++stats_.scan_errors;
      stats_.last_scan_error = "scan " + std::to_string(scan.scan_id()) + ": " + e.what();
    }
  }
  if (opt_.release_large_scans) {
    const WorkingSize& w = opt_.working_size;
    const std::uint64_t points = std::uint64_t(w.steps) * w.rows;
    if (scan.storage_bytes() > ScanLimits::scan_storage_bytes(w.steps, points))
      assembler_.storage().release_storage(w.steps, points);  // the next ScanBegin reserves what it needs
  }
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
    if (::bind(fd, ai->ai_addr, ai->ai_addrlen) != 0 || ::listen(fd, opt_.max_clients) != 0) {
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
  started_ = true;
}

void StreamServer::stop() {
  stop_ = true;
  wake();
}

void StreamServer::wake() {
  const char c = 1;
  [[maybe_unused]] const ssize_t n = ::write(wake_[1], &c, 1);
}

void StreamServer::run() {
  while (poll_once(100)) {
  }
}

bool StreamServer::poll_once(int timeout_ms) {
  if (stop_) return false;
  if (!started_) throw Error("stream server: poll before start()");
  std::vector<pollfd> fds;
  fds.reserve(2 + conns_.size());
  fds.push_back({wake_[0], POLLIN, 0});
  fds.push_back({listen_fd_, POLLIN, 0});  // -1 after close_all(): ignored
  // A connection with a held frame is not read (its fd is left out, so that a hangup does not spin poll).
  for (const auto& c : conns_) fds.push_back({c->has_frame ? -1 : c->fd, POLLIN, 0});
  const std::size_t polled = conns_.size();
  const int n = ::poll(fds.data(), fds.size(), timeout_ms);
  if (n < 0 && errno != EINTR) throw Error(std::string("stream server: poll: ") + std::strerror(errno));
  if (n > 0 && fds[0].revents) {
    char buf[64];
    while (::read(wake_[0], buf, sizeof(buf)) > 0) {
    }
  }
  // Read what arrived, and retry held frames: the consumer may have room again, the scan they waited for
  // may have ended.
  for (std::size_t i = 0; i < polled && i < conns_.size(); ++i) {
    Conn& c = *conns_[i];
    if (c.closed) continue;
    if (c.has_frame || (n > 0 && (fds[2 + i].revents & (POLLIN | POLLHUP | POLLERR)))) service(c);
  }
  if (n > 0 && listen_fd_ >= 0 && (fds[1].revents & POLLIN)) accept_clients();
  for (auto& c : conns_)
    if (c->closed) gaps_closed_ += c->decoder.sequence_gaps();
  std::erase_if(conns_, [](const std::unique_ptr<Conn>& c) { return c->closed; });
  check_timers();
  std::uint64_t gaps = gaps_closed_;
  for (const auto& c : conns_) gaps += c->decoder.sequence_gaps();
  stats_.sequence_gaps = gaps;
  return !stop_;
}

void StreamServer::accept_clients() {
  for (;;) {
    sockaddr_storage ss{};
    socklen_t len = sizeof(ss);
    const int fd =
        ::accept4(listen_fd_, reinterpret_cast<sockaddr*>(&ss), &len, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) return;  // EAGAIN / ECONNABORTED: nothing (more) to do
    char host[NI_MAXHOST] = "?", serv[NI_MAXSERV] = "?";
    ::getnameinfo(reinterpret_cast<sockaddr*>(&ss), len, host, sizeof(host), serv, sizeof(serv),
                  NI_NUMERICHOST | NI_NUMERICSERV);
    const std::string peer =
        ss.ss_family == AF_INET6 ? "[" + std::string(host) + "]:" + serv : std::string(host) + ":" + serv;
    std::size_t open = 0;
    Conn* idle = nullptr;  // the oldest connection that never sent a frame (and is not the scanner)
    for (auto& c : conns_) {
      if (c->closed) continue;
      ++open;
      if (!idle && c->frames == 0 && !c->has_frame && c->id != owner_) idle = c.get();
    }
    if (open >= static_cast<std::size_t>(opt_.max_clients)) {
      if (!idle) {
        ::close(fd);
        ++stats_.refused_connections;
        notice(peer, "connection refused: " + std::to_string(open) +
                         " connections are open and streaming (the limit)");
        continue;
      }
      ++stats_.idle_closed;
      notice(idle->peer, "connection closed: it sent nothing, and " + peer + " needs its place");
      ::close(idle->fd);
      idle->closed = true;
    }
    const int one = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
    auto c = std::make_unique<Conn>(fd, next_id_++, peer);
    c->last_rx_ns = now();
    ++stats_.connections;
    if (owner_ == 0) peer_ = peer;
    send_heartbeat(*c);
    conns_.push_back(std::move(c));
  }
}

void StreamServer::service(Conn& c) {
  std::vector<std::uint8_t>& buf = c.pending;
  try {
    for (int reads = 0; !c.closed;) {
      if (c.has_frame) {
        if (apply(c) == Step::Held) return;
        c.has_frame = false;
        continue;
      }
      if (c.decoder.next(c.frame)) {
        c.has_frame = true;
        ++c.frames;
        ++stats_.frames;
        continue;
      }
      if (c.pending_off < buf.size()) {
        c.pending_off += c.decoder.feed(std::span<const std::uint8_t>(buf).subspan(c.pending_off));
        continue;
      }
      if (++reads > 64) return;  // fairness: the other connections and the timers get their turn
      buf.resize(64 * 1024);
      const ssize_t r = ::recv(c.fd, buf.data(), buf.size(), MSG_DONTWAIT);
      if (r <= 0) buf.clear();
      c.pending_off = 0;
      if (r == 0) {
        drop(c, false);
        return;
      }
      if (r < 0) {
        if (errno == EAGAIN || errno == EWOULDBLOCK) return;
        if (errno == EINTR) continue;
        stats_.last_error = "recv from " + c.peer + ": " + std::strerror(errno);
        drop(c, false);
        return;
      }
      buf.resize(static_cast<std::size_t>(r));
      stats_.bytes += static_cast<std::uint64_t>(r);
      c.last_rx_ns = now();
    }
  } catch (const Error& e) {
    ++stats_.protocol_errors;
    stats_.last_error = "protocol error from " + c.peer + ": " + e.what();
    if (opt_.on_protocol_error) opt_.on_protocol_error(c.peer, e.what());
    const bool cut = c.id == owner_ && assembler_.in_scan();
    c.has_frame = false;
    drop(c, false, cut ? ScanStatus::ProtocolError : ScanStatus::Disconnected);
  }
}

void StreamServer::take_over(Conn& c, const char* why) {
  if (Conn* old = find(owner_); old && old != &c) {
    notice(old->peer, "connection closed: " + c.peer + " " + why);
    ::close(old->fd);
    old->closed = true;
    ++stats_.disconnects;
  }
  if (owner_ != c.id && assembler_.in_scan()) ++stats_.resumed;
  owner_ = c.id;
  peer_ = c.peer;
  disconnected_at_ns_ = -1;
}

StreamServer::Step StreamServer::apply(Conn& c) {
  const msg::Type type = c.frame.header.type;
  const bool in_scan = assembler_.in_scan();
  switch (type) {
    case msg::Type::Heartbeat:
      wire::decode(c.frame, message_, c.decoder.source());
      assembler_.on_message(message_);
      return Step::Applied;
    case msg::Type::Fault:
      wire::decode(c.frame, message_, c.decoder.source());
      if (in_scan && c.id != owner_)
        ++stats_.ignored_frames;  // not the scanner of the scan in progress
      else
        assembler_.on_message(message_);
      return Step::Applied;
    case msg::Type::Stripe:
    case msg::Type::ScanEnd: {
      wire::decode(c.frame, message_, c.decoder.source());
      const std::uint64_t id =
          type == msg::Type::Stripe ? message_.stripe.header.scan_id : message_.scan_end.scan_id;
      if (in_scan && id == assembler_.current().scan_id()) {
        if (type == msg::Type::ScanEnd && !ready()) {
          ++stats_.held_for_queue;
          return Step::Held;
        }
        if (c.id != owner_) take_over(c, ("resumed scan " + std::to_string(id)).c_str());
        protocol_cut_ = false;
      }
      assembler_.on_message(message_);
      if (type == msg::Type::Stripe && in_scan && id == assembler_.current().scan_id()) forward(c);
      return Step::Applied;
    }
    case msg::Type::ScanBegin:
      break;
  }
  // A ScanBegin: it may deliver the scan in progress (superseded) or be refused: both need room.
  if (!ready()) {
    ++stats_.held_for_queue;
    return Step::Held;
  }
  wire::decode(c.frame, message_, c.decoder.source());
  // Another scanner's scan streams: wait for its end. A connection that waited also waits out the grace of a
  // disconnected owner (that scanner may resume); a newcomer after the owner is gone is the scanner moving
  // on.
  if (in_scan && c.id != owner_ && (owner_ != 0 || c.waiting)) {
    if (!c.waiting) {
      c.waiting = true;
      ++stats_.waited_scans;
      const Conn* o = find(owner_);
      notice(c.peer, "scan " + std::to_string(message_.scan_begin.scan_id) + " waits: scan " +
                         std::to_string(assembler_.current().scan_id()) + " streams from " +
                         (o ? o->peer : peer_));
    }
    return Step::Held;
  }
  c.waiting = false;
  c.last_rx_ns = now();
  // A scan cut by a protocol error and not resumed (a new ScanBegin instead) ends as such, not superseded.
  if (protocol_cut_ && in_scan) assembler_.end_of_stream(ScanStatus::ProtocolError);
  protocol_cut_ = false;
  owner_ = c.id;
  peer_ = c.peer;
  disconnected_at_ns_ = -1;
  try {
    assembler_.on_message(message_);
    forward(c);
  } catch (const Error& e) {
    // Refused by the limits (Scan::start): one refused scan, not a protocol error; its stripes are orphans.
    ++stats_.refused_scans;
    if (opt_.on_refused) {
      try {
        opt_.on_refused(c.peer, message_.scan_begin, e.what());
      } catch (const std::exception& e2) {
        ++stats_.scan_errors;
        stats_.last_scan_error =
            "refused scan " + std::to_string(message_.scan_begin.scan_id) + ": " + e2.what();
      }
    }
  }
  return Step::Applied;
}

void StreamServer::forward(const Conn& c) {
  if (!opt_.on_scan_frame) return;
  try {
    opt_.on_scan_frame(c.peer, message_);
  } catch (const std::exception& e) {
    ++stats_.scan_errors;
    stats_.last_scan_error = std::string("forwarding a frame of the scan in progress: ") + e.what();
  }
}

void StreamServer::drop(Conn& c, bool timeout, ScanStatus why) {
  if (c.closed) return;
  ::close(c.fd);
  c.closed = true;
  if (timeout)
    ++stats_.link_timeouts;
  else
    ++stats_.disconnects;
  if (c.id == owner_) {
    owner_ = 0;
    disconnected_at_ns_ = now();
    if (why == ScanStatus::ProtocolError && assembler_.in_scan()) protocol_cut_ = true;
  }
}

void StreamServer::send_heartbeat(Conn& c) {
  msg::Heartbeat hb;
  hb.time_ns = now();
  hb.counter = ++hb_counter_;
  hb.state = 0;
  const std::size_t n = wire::encode(tx_, c.tx_seq++, hb);
  // Best effort: a full socket buffer just skips this heartbeat.
  if (::send(c.fd, tx_.data(), n, MSG_DONTWAIT | MSG_NOSIGNAL) == static_cast<ssize_t>(n))
    ++stats_.heartbeats_sent;
  c.last_hb_ns = now();
}

void StreamServer::check_timers() {
  const std::int64_t t = now();
  for (auto& cp : conns_) {
    Conn& c = *cp;
    if (c.closed) continue;
    if (c.has_frame) c.last_rx_ns = t;  // held by us: not the link's silence
    if (opt_.link_timeout_ms > 0 && t - c.last_rx_ns > opt_.link_timeout_ms * 1'000'000) {
      stats_.last_error = "link timeout: nothing received from " + c.peer + " for " +
                          std::to_string(opt_.link_timeout_ms) + " ms";
      drop(c, true);
    } else if (opt_.heartbeat_interval_ms > 0 && t - c.last_hb_ns >= opt_.heartbeat_interval_ms * 1'000'000) {
      send_heartbeat(c);
    }
  }
  std::erase_if(conns_, [this](const std::unique_ptr<Conn>& c) {
    if (c->closed) gaps_closed_ += c->decoder.sequence_gaps();
    return c->closed;
  });
  if (owner_ == 0 && disconnected_at_ns_ >= 0 && assembler_.in_scan() &&
      t - disconnected_at_ns_ >= opt_.reconnect_grace_ms * 1'000'000 && ready()) {
    disconnected_at_ns_ = -1;
    assembler_.end_of_stream(protocol_cut_ ? ScanStatus::ProtocolError : ScanStatus::Disconnected);
  }
}

void StreamServer::close_all() {
  if (listen_fd_ >= 0) {
    ::close(listen_fd_);
    listen_fd_ = -1;
  }
  for (auto& c : conns_)
    if (!c->closed) ::close(c->fd);
  conns_.clear();
  owner_ = 0;
  assembler_.end_of_stream(protocol_cut_ ? ScanStatus::ProtocolError : ScanStatus::Disconnected);
  disconnected_at_ns_ = -1;
}

// ---- ScanQueue

bool ScanQueue::has_room() const {
  std::lock_guard lock(mu_);
  return jobs_.empty() || (jobs_.size() < max_jobs_ && bytes_ < max_bytes_);
}

void ScanQueue::push(ScanJob job) {
  {
    std::lock_guard lock(mu_);
    bytes_ += job.bytes;
    jobs_.push_back(std::move(job));
  }
  cv_.notify_one();
}

bool ScanQueue::pop(ScanJob& out) {
  std::unique_lock lock(mu_);
  cv_.wait(lock, [this] { return !jobs_.empty() || closed_; });
  if (jobs_.empty()) return false;
  out = std::move(jobs_.front());
  jobs_.pop_front();
  bytes_ -= out.bytes;
  return true;
}

void ScanQueue::close() {
  {
    std::lock_guard lock(mu_);
    closed_ = true;
  }
  cv_.notify_all();
}

std::size_t ScanQueue::size() const {
  std::lock_guard lock(mu_);
  return jobs_.size();
}

std::uint64_t ScanQueue::bytes() const {
  std::lock_guard lock(mu_);
  return bytes_;
}

}  // namespace fs::host
