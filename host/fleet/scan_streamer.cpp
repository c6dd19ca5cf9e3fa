#include "host/fleet/scan_streamer.hpp"

#include <array>
#include <utility>

#include <fmt/format.h>

#include "common/error.hpp"
#include "common/scan_file.hpp"
#include "host/fleet/ids.hpp"

namespace fs::host::fleet {

using Clock = std::chrono::steady_clock;

ScanStreamer::ScanStreamer(NatsConnection& connection, const FleetSettings& settings, std::size_t part_bytes,
                           std::size_t max_queued_bytes)
    : connection_(connection),
      settings_(settings),
      part_bytes_(std::max<std::size_t>(part_bytes, 1)),
      max_queued_bytes_(max_queued_bytes),
      rng_(std::random_device{}()),
      frame_(wire::kMaxFrameSize) {
  thread_ = std::thread([this] { run(); });
}

ScanStreamer::~ScanStreamer() {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void ScanStreamer::push(Task task) {
  {
    std::lock_guard lock(mu_);
    if (task.kind != Kind::Last && queued_bytes_ + task.bytes.size() > max_queued_bytes_) {
      // The server takes parts slower than the scanner sends them: this stream is given up (the scan goes
      // whole through the spool) rather than the stream server's thread waiting.
      overflow_.emplace(task.token,
                        fmt::format("more than {} bytes of parts waiting for the server", max_queued_bytes_));
      return;
    }
    queued_bytes_ += task.bytes.size();
    tasks_.push_back(std::move(task));
  }
  cv_.notify_all();
}

void ScanStreamer::begin(const std::string& scanner_id, const msg::ScanBegin& begin) {
  if (open_ != 0) abandon("a new scan began before this one was delivered");
  std::uint64_t token = 0;
  State s;
  s.scanner = scanner_id;
  s.nonce = rng_();
  s.scan_id = streamed_scan_id(scanner_id, begin.scan_id, begin.start_time_ns, s.nonce);
  open_id_ = s.scan_id;
  s.parts_subject = parts_subject(scanner_id, s.scan_id);
  {
    std::lock_guard lock(mu_);
    token = next_token_++;
    states_.emplace(token, std::move(s));
  }
  open_ = token;
  open_scan_ = begin.scan_id;
  part_.data.clear();
  part_.data.resize(kScanFileHeaderSize);
  encode_scan_file_header(
      std::span<std::uint8_t, kScanFileHeaderSize>(part_.data.data(), kScanFileHeaderSize));
  frame_seq_ = 0;
  const std::size_t n = wire::encode(frame_, frame_seq_++, begin);
  part_.write(std::span<const std::uint8_t>(frame_.data(), n));
  push(Task{token, Kind::Item, {}, {}, Clock::now()});
}

void ScanStreamer::flush_part(Kind kind, std::string status) {
  Task t{open_, kind, std::move(part_.data), std::move(status), Clock::now()};
  part_.data = {};
  push(std::move(t));
}

void ScanStreamer::stripe(const msg::Stripe& stripe) {
  if (open_ == 0 || stripe.header.scan_id != open_scan_) return;
  const std::size_t n = wire::encode(frame_, frame_seq_++, stripe);
  part_.write(std::span<const std::uint8_t>(frame_.data(), n));
  if (part_.data.size() >= part_bytes_) flush_part(Kind::Part);
}

std::uint64_t ScanStreamer::end(const Scan& scan) {
  if (open_ == 0 || scan.scan_id() != open_scan_) return 0;
  if (scan.has_end()) {
    const std::size_t n = wire::encode(frame_, frame_seq_++, scan.end_message());
    part_.write(std::span<const std::uint8_t>(frame_.data(), n));
  }
  const std::uint64_t token = open_;
  flush_part(Kind::Last, to_string(scan.status()));
  open_ = 0;
  return token;
}

void ScanStreamer::abandon(const std::string& why) {
  if (open_ == 0) return;
  {
    std::lock_guard lock(mu_);
    overflow_.emplace(open_, why);
  }
  part_.data.clear();
  flush_part(Kind::Last, kStatusAbandoned);
  open_ = 0;
}

std::string ScanStreamer::open_scan_id() const { return open_ == 0 ? std::string() : open_id_; }

StreamOutcome ScanStreamer::wait(std::uint64_t token) {
  std::unique_lock lock(mu_);
  done_.wait(lock, [&] { return outcomes_.count(token) > 0 || exited_; });
  const auto it = outcomes_.find(token);
  if (it == outcomes_.end()) {
    StreamOutcome none;
    none.error = "the gateway is stopping";
    return none;
  }
  StreamOutcome out = std::move(it->second);
  outcomes_.erase(it);
  return out;
}

void ScanStreamer::finish(std::uint64_t token, StreamOutcome outcome) {
  {
    std::lock_guard lock(mu_);
    outcomes_[token] = std::move(outcome);
    states_.erase(token);
    overflow_.erase(token);
  }
  done_.notify_all();
}

void ScanStreamer::publish(State& s, const Task& t) {
  const bool item = t.kind == Kind::Item;
  const std::string subject = item ? scans_subject(s.scanner) : s.parts_subject;
  // The "abandoned" marker has an id of its own: a part whose publish timed out may be stored after all,
  // and the marker must not be taken for its duplicate.
  const bool abandon = t.kind == Kind::Last && t.status == kStatusAbandoned;
  const std::string msg_id =
      item ? s.scan_id : (abandon ? s.scan_id + "-abandoned" : part_message_id(s.scan_id, s.next_part));
  const std::int64_t max_payload = connection_.max_payload();
  if (max_payload > 0 && static_cast<std::int64_t>(t.bytes.size()) > max_payload)
    throw Error(fmt::format("part {} of {} bytes exceeds the server's max_payload of {} bytes", s.next_part,
                            t.bytes.size(), max_payload));
  if (item) s.item_sent = true;  // from the first attempt on it may be stored (a timed-out publish may be)
  NatsHeaders headers = {{kHeaderScanId, s.scan_id}, {kHeaderScanner, s.scanner}};
  if (item) {
    headers.insert(headers.end(), {{kHeaderStatus, "streaming"}, {kHeaderParts, s.parts_subject}});
  } else {
    headers.emplace_back(kHeaderPart, std::to_string(s.next_part));
    if (t.kind == Kind::Last) headers.insert(headers.end(), {{kHeaderLast, "1"}, {kHeaderStatus, t.status}});
  }
  for (int attempt = 0;; ++attempt) {
    JsPublished ack;
    jsErrCode err = static_cast<jsErrCode>(0);
    const natsStatus st = js_publish_once(connection_.js(), subject, msg_id,
                                          item ? kScansStream : kPartsStream, t.bytes, headers, ack, err);
    if (st == NATS_OK) break;
    // A timeout may be a slow acknowledgement: the same message id again is stored once. Anything else, or
    // a third timeout, abandons the stream (the scan goes whole through the spool).
    if (st != NATS_TIMEOUT || attempt >= 2)
      throw_nats(st, fmt::format("publish {} to {}", msg_id, subject), err);
  }
  if (!item) {
    ++s.next_part;
    ++s.parts;
    s.bytes += t.bytes.size();
  }
}

bool ScanStreamer::announce_abandoned(State& s) {
  if (!connection_.connected()) return false;
  try {
    publish(s, Task{0, Kind::Last, {}, kStatusAbandoned, Clock::now()});
    return true;
  } catch (const Error&) {
    return false;
  }
}

void ScanStreamer::run() {
  auto next_retry = Clock::now();
  for (;;) {
    Task t;
    State* s = nullptr;
    std::string overflow;
    bool have_task = false;
    {
      std::unique_lock lock(mu_);
      const auto ready = [&] { return stop_ || !tasks_.empty(); };
      if (pending_.empty())
        cv_.wait(lock, ready);
      else
        cv_.wait_until(lock, next_retry, ready);
      if (stop_ && tasks_.empty()) {
        exited_ = true;
        done_.notify_all();
        return;
      }
      if (!tasks_.empty()) {
        t = std::move(tasks_.front());
        tasks_.pop_front();
        queued_bytes_ -= t.bytes.size();
        const auto it = states_.find(t.token);
        if (it != states_.end()) {
          have_task = true;
          s = &it->second;  // erased only by finish() on this thread
          if (const auto o = overflow_.find(t.token); o != overflow_.end()) overflow = o->second;
        }
      }
    }
    // Abandoned streams not announced yet: every 250 ms, between the tasks (which go on meanwhile).
    if (!pending_.empty() && Clock::now() >= next_retry) {
      std::erase_if(pending_, [&](State& p) { return announce_abandoned(p); });
      next_retry = Clock::now() + std::chrono::milliseconds(250);
    }
    if (!have_task) continue;
    if (!s->failed && !overflow.empty()) {
      s->failed = true;
      s->error = overflow;
    }
    if (!s->failed) {
      try {
        if (!connection_.connected()) throw Error("NATS unreachable");
        if (!parts_checked_) {
          ensure_parts_stream(connection_.js(), settings_, true);
          parts_checked_ = true;
        }
        publish(*s, t);
      } catch (const Error& e) {
        s->failed = true;
        s->error = e.what();
      }
    }
    if (t.kind != Kind::Last) continue;
    StreamOutcome out;
    out.scan_id = s->scan_id;
    out.nonce = s->nonce;
    out.scanner = s->scanner;
    out.parts = s->parts;
    out.bytes = s->bytes;
    out.last_ms = std::chrono::duration<double, std::milli>(Clock::now() - t.queued).count();
    if (!s->failed && t.status != kStatusAbandoned) {
      out.stored = true;
    } else {
      out.error = s->error.empty() ? "abandoned" : s->error;
      // A worker may hold the scan only when its SCANS message may have been stored: tell it to drop it (now,
      // or when the server is back). At most kMaxPending wait; beyond, the oldest is left to the workers'
      // part timeout.
      if (s->item_sent) {
        State copy = *s;
        if (!announce_abandoned(copy)) {
          if (pending_.size() >= kMaxPending) pending_.erase(pending_.begin());
          pending_.push_back(std::move(copy));
        }
      }
    }
    finish(t.token, std::move(out));
  }
}

}  // namespace fs::host::fleet
