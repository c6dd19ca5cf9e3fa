#include "host/fleet/gateway.hpp"

#include <cstdio>
#include <optional>
#include <utility>

#include <fmt/format.h>

#include "common/byte_size.hpp"
#include "common/error.hpp"
#include "host/fleet/ids.hpp"
#include "host/io/scan_bytes.hpp"

namespace fs::host::fleet {

using Clock = std::chrono::steady_clock;

std::string scanner_id_from_peer(const std::string& peer) {
  std::string host = peer;
  if (!host.empty() && host.front() == '[') {  // [v6]:port
    const auto close = host.find(']');
    host = host.substr(1, close == std::string::npos ? std::string::npos : close - 1);
  } else if (const auto colon = host.rfind(':'); colon != std::string::npos) {
    host = host.substr(0, colon);
  }
  std::string id;
  for (char c : host) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9');
    id += ok ? c : '-';
  }
  if (id.empty()) id = "unknown";
  if (id.size() > 64) id.resize(64);
  return id;
}

Gateway::Gateway(GatewayOptions options)
    : options_(std::move(options)), spool_(options_.spool_dir, options_.spool_max_bytes) {
  if (!options_.scanner_id.empty()) check_scanner_id(options_.scanner_id, "--scanner");
  NatsOptions no = options_.nats;
  no.connect_in_background = true;
  if (no.name.empty()) no.name = "facetscan-gateway";
  no.js_wait_ms = std::min<std::int64_t>(no.js_wait_ms, 5000);
  connection_ = std::make_unique<NatsConnection>(no);
  stats_.spooled = spool_.count();
  stats_.spool_bytes = stats_.spool_peak_bytes = spool_.bytes();
  if (stats_.spooled > 0)
    log(fmt::format("spool {}: {} scan(s) ({}) left by a previous run, sent first", spool_.dir().string(),
                    stats_.spooled, format_byte_size(stats_.spool_bytes)));
  if (options_.stream)
    streamer_ = std::make_unique<ScanStreamer>(*connection_, options_.settings, options_.part_bytes);
  sender_ = std::thread([this] { send_loop(); });
}

Gateway::~Gateway() {
  if (sender_.joinable()) stop(std::chrono::milliseconds(0));
}

void Gateway::log(const std::string& line) const {
  if (options_.log) {
    options_.log(line);
  } else {
    std::fputs(("facetscan serve: " + line + "\n").c_str(), stdout);
    std::fflush(stdout);
  }
}

std::string Gateway::spool_text() const {
  return fmt::format("{} scan(s), {} of {} in {}", spool_.count(), format_byte_size(spool_.bytes()),
                     format_byte_size(spool_.max_bytes()), spool_.dir().string());
}

std::string Gateway::scanner_of(const std::string& peer) const {
  return options_.scanner_id.empty() ? scanner_id_from_peer(peer) : options_.scanner_id;
}

void Gateway::stream_frame(const std::string& peer, const wire::DecodedMessage& message) {
  if (!streamer_) return;
  if (message.type == msg::Type::ScanBegin)
    streamer_->begin(scanner_of(peer), message.scan_begin);
  else if (message.type == msg::Type::Stripe)
    streamer_->stripe(message.stripe);
}

std::uint64_t Gateway::stream_end(const Scan& scan, bool taken) {
  if (!streamer_) return 0;
  if (!taken) {
    streamer_->abandon("not taken (--max-scans)");
    return 0;
  }
  return streamer_->end(scan);
}

void Gateway::submit(const Scan& scan, const std::string& peer, bool stopping, std::uint64_t stream) {
  std::string scanner = scanner_of(peer);
  std::optional<std::uint64_t> nonce;  // a streamed scan sent whole keeps its streamed id
  if (stream != 0 && streamer_) {
    const StreamOutcome o = streamer_->wait(stream);
    std::lock_guard lock(mu_);
    ++stats_.received;
    if (o.stored) {
      ++stats_.published;
      ++stats_.streamed;
      stats_.publish_ms.push_back(o.last_ms);
      if (!options_.quiet)
        log(fmt::format(
            "scan {} streamed as {} ({} part(s), {}; last part stored {:.1f} ms after the scan's end)",
            scan.scan_id(), o.scan_id, o.parts, format_byte_size(o.bytes), o.last_ms));
      return;
    }
    ++stats_.stream_failures;
    log(fmt::format("streaming scan {} as {} failed ({}): it goes whole through the spool", scan.scan_id(),
                    o.scan_id, o.error));
    --stats_.received;  // counted below
    if (!o.scanner.empty()) {
      scanner = o.scanner;
      nonce = o.nonce;
    }
  }
  const std::vector<std::uint8_t> image = encode_scan_bytes(scan);
  {
    std::unique_lock lock(mu_);
    ++stats_.received;
    if (!spool_.has_room(image.size()) && !stopping && !released_) {
      log(
          fmt::format("spool full ({}): scan {} from {} waits, the scanners are held until the server takes "
                      "scans",
                      spool_text(), scan.scan_id(), peer));
      cv_.wait(lock, [&] { return stop_ || released_ || spool_.has_room(image.size()); });
    }
  }
  const SpoolEntry e = spool_.put(image, scanner, scan.status(), nonce);
  std::lock_guard lock(mu_);
  stats_.spooled = spool_.count();
  stats_.spool_bytes = spool_.bytes();
  stats_.spool_peak_bytes = std::max(stats_.spool_peak_bytes, stats_.spool_bytes);
  if (unreachable_ || stats_.spooled > 1)
    log(fmt::format("scan {} from {} ({}, {}) spooled as #{}; spool: {}", scan.scan_id(), peer, scanner,
                    format_byte_size(e.bytes), e.sequence, spool_text()));
  cv_.notify_all();
}

bool Gateway::send_one(const SpoolEntry& entry) {
  std::vector<std::uint8_t> image;
  msg::ScanBegin begin;
  try {
    image = spool_.read(entry);
    begin = peek_scan_begin(image, entry.path.string());
  } catch (const Error& e) {
    const auto to = spool_.reject(entry, e.what());
    std::lock_guard lock(mu_);
    ++stats_.rejected;
    log(fmt::format("FAILED: spooled scan #{} is unreadable, moved to {}: {}", entry.sequence, to.string(),
                    e.what()));
    return true;
  }
  const std::int64_t max_payload = connection_->max_payload();
  if (max_payload > 0 && static_cast<std::int64_t>(image.size()) > max_payload) {
    const std::string reason = fmt::format(
        "{} bytes exceed the NATS server's max_payload of {} bytes (raise max_payload in the "
        "server config, toolchain/deploy/nats/); publish it later with `facetscan submit`",
        image.size(), max_payload);
    const auto to = spool_.reject(entry, reason);
    std::lock_guard lock(mu_);
    ++stats_.rejected;
    log(fmt::format("FAILED: scan {} (#{}) moved to {}: {}", begin.scan_id, entry.sequence, to.string(),
                    reason));
    return true;
  }
  PublishedScan p;
  try {
    auto& publisher = publishers_[entry.scanner_id];
    if (!publisher)
      publisher = std::make_unique<ScanPublisher>(*connection_, entry.scanner_id, options_.settings);
    // A streamed scan sent whole keeps its streamed id: if its stream reached a worker after all (a publish
    // that timed out but was stored), RESULTS takes one result of the two.
    const std::string id = entry.stream_nonce ? streamed_scan_id(entry.scanner_id, begin.scan_id,
                                                                 begin.start_time_ns, *entry.stream_nonce)
                                              : std::string();
    p = publisher->publish(image, to_string(entry.status), 1, id);
  } catch (const Error& e) {
    std::lock_guard lock(mu_);
    if (!unreachable_) {
      unreachable_ = true;
      ++stats_.outages;
      log(fmt::format("NATS not taking scans ({}): they stay in the spool ({}) and are sent when it does",
                      e.what(), spool_text()));
    }
    return false;
  }
  spool_.remove(entry);
  std::lock_guard lock(mu_);
  if (unreachable_) {
    unreachable_ = false;
    log(fmt::format("NATS takes scans again ({}): sending the spool ({})", connection_->connected_url(),
                    spool_text()));
  }
  ++(p.duplicate ? stats_.duplicates : stats_.published);
  stats_.publish_ms.push_back(p.ms);
  stats_.spooled = spool_.count();
  stats_.spool_bytes = spool_.bytes();
  if (!options_.quiet)
    log(fmt::format("scan {} published to {} as {} ({}, {:.1f} ms, SCANS seq {}{}){}", begin.scan_id,
                    p.subject, p.message_id, format_byte_size(p.bytes), p.ms, p.sequence,
                    p.duplicate ? ", already stored" : "",
                    stats_.spooled > 0 ? fmt::format("; spool: {}", spool_text()) : ""));
  cv_.notify_all();  // room in the spool
  return true;
}

void Gateway::send_loop() {
  Clock::time_point drain_until = Clock::time_point::max();
  for (;;) {
    {
      std::unique_lock lock(mu_);
      cv_.wait_for(lock, std::chrono::milliseconds(250), [&] { return stop_ || spool_.count() > 0; });
      if (stop_) {
        if (drain_until == Clock::time_point::max()) drain_until = drain_deadline_;
        if (spool_.count() == 0 || Clock::now() >= drain_until) return;
      }
    }
    const std::optional<SpoolEntry> e = spool_.oldest();
    if (!e) continue;
    if (!connection_->connected() || !send_one(*e)) {
      if (!connection_->connected()) {
        std::lock_guard lock(mu_);
        if (!unreachable_) {
          unreachable_ = true;
          ++stats_.outages;
          log(fmt::format("NATS unreachable: scans stay in the spool ({}) and are sent when it returns",
                          spool_text()));
        }
      }
      std::unique_lock lock(mu_);
      cv_.wait_for(lock, std::chrono::milliseconds(250),
                   [&] { return stop_ && Clock::now() >= drain_deadline_; });
    }
  }
}

void Gateway::release_waiters() {
  {
    std::lock_guard lock(mu_);
    released_ = true;
  }
  cv_.notify_all();
}

std::size_t Gateway::stop(std::chrono::milliseconds drain) {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
    drain_deadline_ = Clock::now() + drain;
  }
  cv_.notify_all();
  if (sender_.joinable()) sender_.join();
  return spool_.count();
}

GatewayStats Gateway::stats() const {
  std::lock_guard lock(mu_);
  GatewayStats s = stats_;
  s.spooled = spool_.count();
  s.spool_bytes = spool_.bytes();
  return s;
}

}  // namespace fs::host::fleet
