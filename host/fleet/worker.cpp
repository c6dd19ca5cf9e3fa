#include "host/fleet/worker.hpp"

#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <span>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/error.hpp"
#include "host/fleet/ids.hpp"
#include "host/io/scan_bytes.hpp"

namespace fs::host::fleet {

namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace

struct Worker::Job {
  std::uint64_t id = 0;  // this worker's number for it
  natsMsg* msg = nullptr;
  std::string scan_id;
  std::string scanner_id;
  std::string status;
  std::uint64_t deliveries = 1;
  std::int64_t stored_ns = 0;  // when the stream stored the scan (UTC)
  Clock::time_point marked;    // last marked in progress
  bool settled = false;        // acked, nak'ed or terminated: no more marking (mu_)
  // A streamed scan: the subject of its parts, the parts joined so far, the subscription reading them.
  std::string parts_subject;
  natsSubscription* parts_sub = nullptr;
  std::vector<std::uint8_t> parts;
  std::uint64_t next_part = 0;
  Clock::time_point last_part;
  // The last part stored -> received: the broker's share after the scan's end.
  double last_part_wait_ms = 0.0;
  std::int64_t taken_ns = 0;        // when this worker took the scan (UTC)
  std::int64_t last_stored_ns = 0;  // when PARTS stored its last part (UTC)
  bool abandoned = false;           // its gateway sends it whole instead
  std::string failure;              // reading the parts failed

  bool streamed() const { return !parts_subject.empty(); }
  std::span<const std::uint8_t> image() const {
    if (streamed()) return parts;
    return {reinterpret_cast<const std::uint8_t*>(natsMsg_GetData(msg)),
            static_cast<std::size_t>(natsMsg_GetDataLength(msg))};
  }
};

// The closure of a streamed scan's part subscription: the scan is found by its number (a late part meets no
// released scan); freed when the subscription has delivered its last callback
// (natsSubscription_SetOnCompleteCB), and run() waits for that before it returns.
struct Worker::PartClosure {
  Worker* worker;
  std::uint64_t job;
};

void Worker::free_part_closure(void* closure) {
  auto* c = static_cast<PartClosure*>(closure);
  Worker* w = c->worker;
  delete c;
  std::lock_guard lock(w->closures_mu_);
  --w->live_closures_;
  w->closures_cv_.notify_all();
}

std::string default_worker_id() {
  char host[256] = {0};
  if (gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  std::string h = host;
  for (char& c : h)
    if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-')) c = '_';
  return fmt::format("{}-{}", h.empty() ? "worker" : h, static_cast<long>(getpid()));
}

Worker::Worker(NatsConnection& connection, const Library& library, WorkerOptions options)
    : connection_(connection), library_(library), options_(std::move(options)) {
  if (options_.worker_id.empty()) options_.worker_id = default_worker_id();
  if (options_.threads < 1) options_.threads = 1;
  consumer_ = ensure_fleet(connection_.js(), options_.settings);
  // Scans whose every delivery timed out: the server announces them once; one worker (queue group) moves
  // each to DEAD.
  const std::string advisory =
      fmt::format("$JS.EVENT.ADVISORY.CONSUMER.MAX_DELIVERIES.{}.{}", kScansStream, kWorkersConsumer);
  const natsStatus st = natsConnection_QueueSubscribe(&advisory_sub_, connection_.get(), advisory.c_str(),
                                                      "facetscan-dead-letters", &Worker::on_advisory, this);
  if (st != NATS_OK) throw_nats(st, "subscribe to " + advisory);
}

Worker::~Worker() { connection_.end_subscription(advisory_sub_); }

void Worker::say(const std::string& line) {
  if (!options_.log) return;
  std::lock_guard lock(log_mutex_);
  options_.log(fmt::format("worker {}: {}", options_.worker_id, line));
}

void Worker::run(const std::atomic<bool>& stop) {
  say(fmt::format("ready ({} thread(s), {} stream(s), AckWait {} ms, MaxDeliver {}, library {} {})",
                  options_.threads, options_.max_streams, consumer_.ack_wait_ms, consumer_.max_deliver,
                  options_.library_id, options_.library_hash));
  std::atomic<bool> ticker_stop{false};
  std::thread ticker([this, &ticker_stop] { ticker_main(ticker_stop); });
  std::thread fetcher([this, &stop] { fetch_main(stop); });
  std::vector<std::thread> threads;
  for (int i = 0; i < options_.threads; ++i) threads.emplace_back([this, &stop] { recognize_main(stop); });
  fetcher.join();
  for (auto& t : threads) t.join();
  // Stopping: what is held and not recognized goes back to the consumer now (another worker takes it).
  std::vector<std::unique_ptr<Job>> left;
  {
    std::lock_guard lock(mu_);
    for (auto& j : ready_) left.push_back(std::move(j));
    for (auto& [id, j] : collecting_) left.push_back(std::move(j));
    ready_.clear();
    collecting_.clear();
  }
  for (auto& j : left) {
    {
      std::lock_guard lock(mu_);
      j->settled = true;
    }
    natsMsg_Nak(j->msg, nullptr);
    release(std::move(j));
  }
  ticker_stop = true;
  ticker.join();
  // Destroyed, not ended: an unsubscribe would delete a consumer the library made, and the pull subscriptions
  // get messages only for a fetch (none is waiting now).
  for (natsSubscription* sub : pull_subs_) natsSubscription_Destroy(sub);
  pull_subs_.clear();
  {
    // The part subscriptions' last callbacks (their closures point here).
    std::unique_lock cl(closures_mu_);
    closures_cv_.wait_for(cl, std::chrono::seconds(30), [&] { return live_closures_ == 0; });
  }
  say(
      fmt::format("stopped: {} result(s) ({} streamed), {} duplicate(s), {} failure(s), {} dead-lettered, {} "
                  "abandoned stream(s)",
                  counters_.results.load(), counters_.streamed.load(), counters_.duplicates.load(),
                  counters_.failures.load(), counters_.dead.load(), counters_.abandoned.load()));
}

void Worker::fetch_main(const std::atomic<bool>& stop) {
  natsSubscription* sub = nullptr;
  int errors = 0;
  const std::string subject = std::string(kScansPrefix) + ">";
  while (!stop.load()) {
    {
      // Room: a recognizer free for a whole scan, and a stream slot for a streamed one (which it is shows
      // only once fetched).
      std::unique_lock lock(mu_);
      const auto room = [&] {
        return ready_.size() + recognizing_ < static_cast<std::size_t>(options_.threads) &&
               collecting_.size() < static_cast<std::size_t>(options_.max_streams);
      };
      room_cv_.wait_for(lock, std::chrono::milliseconds(250), [&] { return stop.load() || room(); });
      if (stop.load() || !room()) continue;
    }
    if (sub == nullptr) {
      jsSubOptions so;
      jsSubOptions_Init(&so);
      so.Stream = kScansStream;
      so.Consumer = kWorkersConsumer;
      jsErrCode err = static_cast<jsErrCode>(0);
      const natsStatus st =
          js_PullSubscribe(&sub, connection_.js(), subject.c_str(), kWorkersConsumer, nullptr, &so, &err);
      if (st == NATS_OK) {
        // Kept until every scan fetched through it is released: a message's ack goes through its
        // subscription.
        std::lock_guard lock(mu_);
        pull_subs_.push_back(sub);
      } else {
        sub = nullptr;
        if (errors++ % 20 == 0) say(nats_error_text(st, "pull subscribe", err));
        std::this_thread::sleep_for(std::chrono::milliseconds(250));
        continue;
      }
    }
    natsMsgList list{nullptr, 0};
    jsErrCode err = static_cast<jsErrCode>(0);
    const natsStatus st = natsSubscription_Fetch(&list, sub, 1, 1000, &err);
    if (st == NATS_TIMEOUT) continue;
    if (st != NATS_OK) {
      // The server restarting, a cluster electing a consumer leader: wait; after repeated failures the
      // subscription is made again.
      if (errors++ % 20 == 0) say(nats_error_text(st, "fetch", err));
      if (errors % 10 == 0) sub = nullptr;  // a new one next time; this one lives on (run() ends it)
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
      continue;
    }
    errors = 0;
    for (int i = 0; i < list.Count; ++i) {
      auto job = std::make_unique<Job>();
      job->msg = list.Msgs[i];
      list.Msgs[i] = nullptr;  // the job owns it
      take(std::move(job));
    }
    natsMsgList_Destroy(&list);
  }
}

void Worker::take(std::unique_ptr<Job> job) {
  natsMsg* m = job->msg;
  jsMsgMetaData* meta = nullptr;
  if (natsMsg_GetMetaData(&meta, m) == NATS_OK) {
    job->deliveries = meta->NumDelivered;
    job->stored_ns = meta->Timestamp;
    jsMsgMetaData_Destroy(meta);
  }
  job->scanner_id = scanner_of_subject(natsMsg_GetSubject(m), kScansPrefix);
  job->scan_id = nats_header(m, kHeaderScanId);
  job->status = nats_header(m, kHeaderStatus);
  job->parts_subject = nats_header(m, kHeaderParts);
  job->taken_ns = nats_NowInNanoSeconds();
  job->marked = Clock::now();
  Job* j = job.get();
  std::unique_lock lock(mu_);
  j->id = next_job_++;
  held_.push_back(j);
  if (!j->streamed()) {
    ready_.push_back(std::move(job));
    ready_cv_.notify_one();
    return;
  }
  // A streamed scan: its parts are read as they come (from the first, also on a redelivery).
  say(fmt::format("reading the parts of {} (delivery {})", j->scan_id, j->deliveries));
  j->last_part = Clock::now();
  const std::uint64_t id = j->id;
  const std::string subject = j->parts_subject, scan_id = j->scan_id;
  collecting_.emplace(id, std::move(job));
  const std::string prefix = std::string(kPartsPrefix) + j->scanner_id + ".";
  if (j->scanner_id.empty() || subject.rfind(prefix, 0) != 0) {
    j->failure = fmt::format("{} '{}' is not a subject of scanner '{}' in PARTS", kHeaderParts, subject,
                             j->scanner_id);
    ready(j);
    return;
  }
  lock.unlock();
  // Subscribed without mu_ (the call may wait for the server): meanwhile the scan may have all its parts,
  // time out, even be released; it is found again by its number.
  jsSubOptions so;
  jsSubOptions_Init(&so);
  so.Stream = kPartsStream;
  so.Ordered = true;
  auto closure = std::make_unique<PartClosure>(PartClosure{this, id});
  {
    std::lock_guard cl(closures_mu_);
    ++live_closures_;
  }
  natsSubscription* sub = nullptr;
  jsErrCode err = static_cast<jsErrCode>(0);
  const natsStatus st = js_Subscribe(&sub, connection_.js(), subject.c_str(), &Worker::on_part, closure.get(),
                                     nullptr, &so, &err);
  if (st == NATS_OK &&
      natsSubscription_SetOnCompleteCB(sub, &Worker::free_part_closure, closure.get()) == NATS_OK)
    closure.release();  // freed by free_part_closure
  if (closure) {        // no on-complete callback will come: kept until the worker is destroyed
    std::lock_guard cl(closures_mu_);
    --live_closures_;
    orphan_closures_.push_back(std::move(closure));
  }
  lock.lock();
  const auto held = std::find_if(held_.begin(), held_.end(), [&](const Job* h) { return h->id == id; });
  if (st != NATS_OK) {
    if (collecting_.count(id) > 0) {
      collecting_[id]->failure = nats_error_text(st, "read the parts of " + scan_id, err);
      ready(collecting_[id].get());
    }
  } else if (held != held_.end()) {
    (*held)->parts_sub = sub;  // release() ends it
    sub = nullptr;
  }
  lock.unlock();
  if (sub != nullptr) connection_.end_subscription(sub);  // the scan was released meanwhile
}

void Worker::ready(Job* job) {
  const auto it = collecting_.find(job->id);
  if (it == collecting_.end()) return;
  ready_.push_back(std::move(it->second));
  collecting_.erase(it);
  ready_cv_.notify_one();
  room_cv_.notify_all();
}

void Worker::on_part(natsConnection*, natsSubscription*, natsMsg* msg, void* closure) {
  const auto* c = static_cast<const PartClosure*>(closure);
  Worker& w = *c->worker;
  {
    std::lock_guard lock(w.mu_);
    const auto it = w.collecting_.find(c->job);
    if (it != w.collecting_.end()) {
      Job& j = *it->second;
      const std::string last = nats_header(msg, kHeaderLast);
      const std::string status = nats_header(msg, kHeaderStatus);
      std::uint64_t n = 0;
      const std::string part = nats_header(msg, kHeaderPart);
      const bool numbered =
          !part.empty() && part.find_first_not_of("0123456789") == std::string::npos && part.size() < 20;
      if (numbered) n = std::stoull(part);
      j.last_part = Clock::now();
      if (!last.empty() && status == kStatusAbandoned) {
        j.abandoned = true;
        w.ready(&j);
      } else if (!numbered) {
        j.failure = fmt::format("part without a valid {} header ('{}')", kHeaderPart, part);
        w.ready(&j);
      } else if (n < j.next_part) {
        // a part stored twice (a publish retried after the server restarted): already have it
      } else if (n > j.next_part) {
        j.failure = fmt::format("part {} arrived where part {} was expected", n, j.next_part);
        w.ready(&j);
      } else {
        const auto* d = reinterpret_cast<const std::uint8_t*>(natsMsg_GetData(msg));
        j.parts.insert(j.parts.end(), d, d + natsMsg_GetDataLength(msg));
        ++j.next_part;
        if (!last.empty()) {
          j.status = status;
          jsMsgMetaData* meta = nullptr;
          if (natsMsg_GetMetaData(&meta, msg) == NATS_OK) {
            j.last_part_wait_ms = static_cast<double>(nats_NowInNanoSeconds() - meta->Timestamp) / 1e6;
            j.last_stored_ns = meta->Timestamp;
            jsMsgMetaData_Destroy(meta);
          }
          w.ready(&j);
        }
      }
    }
  }
  natsMsg_Destroy(msg);
}

void Worker::ticker_main(const std::atomic<bool>& stop) {
  const auto period = std::chrono::milliseconds(std::max<std::int64_t>(consumer_.ack_wait_ms / 3, 50));
  const auto timeout = std::chrono::milliseconds(std::max<std::int64_t>(options_.part_timeout_ms, 1));
  while (!stop.load()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(std::min<std::int64_t>(period.count(), 100)));
    std::lock_guard lock(mu_);
    const auto now = Clock::now();
    for (Job* j : held_)
      if (!j->settled && now - j->marked >= period) {
        natsMsg_InProgress(j->msg, nullptr);
        j->marked = now;
      }
    std::vector<Job*> stalled;
    for (auto& [id, j] : collecting_)
      if (now - j->last_part >= timeout) stalled.push_back(j.get());
    for (Job* j : stalled) {
      j->failure =
          fmt::format("no part for {} ms after {} part(s) ({} bytes): its gateway stopped streaming it",
                      options_.part_timeout_ms, j->next_part, j->parts.size());
      ready(j);
    }
  }
}

void Worker::recognize_main(const std::atomic<bool>& stop) {
  std::unique_ptr<rec::Recognizer> recognizer;
  std::size_t recognizer_cells = 0;
  for (;;) {
    std::unique_ptr<Job> job;
    {
      std::unique_lock lock(mu_);
      ready_cv_.wait_for(lock, std::chrono::milliseconds(250),
                         [&] { return stop.load() || !ready_.empty(); });
      if (stop.load()) return;
      if (ready_.empty()) continue;
      job = std::move(ready_.front());
      ready_.pop_front();
      ++recognizing_;
    }
    process(*job, stop, recognizer, recognizer_cells);
    {
      std::lock_guard lock(mu_);
      --recognizing_;
    }
    release(std::move(job));
  }
}

void Worker::release(std::unique_ptr<Job> job) {
  natsSubscription* sub = nullptr;
  {
    std::lock_guard lock(mu_);
    std::erase(held_, job.get());
    sub = std::exchange(job->parts_sub, nullptr);
  }
  connection_.end_subscription(sub);
  natsMsg_Destroy(job->msg);
  job.reset();
  room_cv_.notify_all();
}

bool Worker::term_sync(natsMsg* m) {
  // With a wait the termination is a request: its parts may be purged only once the server has it (else
  // the scan comes back and needs them).
  jsOptions o;
  jsOptions_Init(&o);
  o.Wait = std::max<std::int64_t>(connection_.options().js_wait_ms, 1);
  return natsMsg_Term(m, &o) == NATS_OK;
}

void Worker::purge_parts(const Job& job) {
  if (!job.streamed()) return;
  jsOptions o;
  jsOptions_Init(&o);
  o.Stream.Purge.Subject = job.parts_subject.c_str();
  jsErrCode err = static_cast<jsErrCode>(0);
  const natsStatus st = js_PurgeStream(connection_.js(), kPartsStream, &o, &err);
  if (st != NATS_OK)
    say(nats_error_text(
        st, fmt::format("purge the parts of {} (they expire with PARTS' max age)", job.scan_id), err));
}

bool Worker::publish_retrying(const char* subject, const std::string& msg_id, const std::string& body,
                              const std::vector<std::pair<std::string, std::string>>& headers,
                              const char* stream, const std::atomic<bool>& stop, bool& duplicate) {
  const std::span<const std::uint8_t> bytes(reinterpret_cast<const std::uint8_t*>(body.data()), body.size());
  for (int attempt = 0;; ++attempt) {
    JsPublished ack;
    jsErrCode err = static_cast<jsErrCode>(0);
    const natsStatus st =
        js_publish_once(connection_.js(), subject, msg_id, stream, bytes, headers, ack, err);
    if (st == NATS_OK) {
      duplicate = ack.duplicate;
      return true;
    }
    if (attempt % 20 == 0) say(nats_error_text(st, fmt::format("publish {} to {}", msg_id, subject), err));
    // Not stored: keep trying while the server is away; on stop the scan stays unacked (redelivered).
    if (stop.load() || (!nats_transient(st) && attempt >= 3)) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
}

void Worker::process(Job& job, const std::atomic<bool>& stop, std::unique_ptr<rec::Recognizer>& recognizer,
                     std::size_t& recognizer_cells) {
  const auto t0 = Clock::now();
  natsMsg* m = job.msg;
  // Settles the scan (ack, nak or term follow): it is no longer marked in progress.
  const auto settle = [&] {
    std::lock_guard lock(mu_);
    job.settled = true;
  };
  const std::span<const std::uint8_t> image = job.image();
  const double queued_ms =
      job.stored_ns > 0 ? static_cast<double>(nats_NowInNanoSeconds() - job.stored_ns) / 1e6 : 0.0;
  if (job.abandoned) {
    settle();
    if (term_sync(m)) purge_parts(job);
    counters_.abandoned.fetch_add(1);
    say(fmt::format("dropped {}: its gateway abandoned the stream and sends the scan whole", job.scan_id));
    return;
  }
  say(fmt::format("recognizing {} (delivery {}{})", job.scan_id.empty() ? "?" : job.scan_id, job.deliveries,
                  job.streamed() ? fmt::format(", {} part(s)", job.next_part) : ""));

  if (options_.test_hold_ms > 0) {
    const auto until = Clock::now() + std::chrono::milliseconds(options_.test_hold_ms);
    while (Clock::now() < until && !stop.load()) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (stop.load()) {
      settle();
      natsMsg_Nak(m, nullptr);  // stopping: another worker takes it now
      return;
    }
  }

  nlohmann::json result;
  std::string failure;
  double load_ms = 0.0, recognize_ms = 0.0;
  try {
    if (!job.failure.empty()) throw Error(job.failure);
    const std::string name = job.scan_id.empty() ? "scan" : job.scan_id;
    if (job.scan_id.empty() || job.scanner_id.empty())
      throw Error(fmt::format("{}: no {} header or no scanner in subject '{}'", name, kHeaderScanId,
                              natsMsg_GetSubject(m)));
    OrganizedCloud cloud;
    LoadOptions lo;
    lo.limits = options_.limits;
    const auto tl = Clock::now();
    const LoadInfo info = load_cloud_bytes(image, name, cloud, lo);
    load_ms = ms_since(tl);
    const auto tr = Clock::now();
    // One recognizer per thread, sized by the largest scan so far (warm for the next ones).
    if (!recognizer || cloud.points.size() > recognizer_cells) {
      recognizer_cells = std::max<std::size_t>(cloud.points.size(), 1);
      recognizer = std::make_unique<rec::Recognizer>(library_, options_.params, recognizer_cells);
    }
    const rec::Recognition& r = recognizer->recognize(cloud);
    recognize_ms = ms_since(tr);
    result = rec::to_json(r, library_);
    result["input"] = {{"format", info.format},
                       {"width", cloud.width},
                       {"height", cloud.height},
                       {"valid_points", info.valid_points},
                       {"complete_scan", info.complete_scan},
                       {"scan_status", info.scan_status},
                       {"stripe_points", info.stripe_points},
                       {"bytes", image.size()}};
  } catch (const std::exception& e) {
    failure = e.what();
  }
  if (!failure.empty()) {
    counters_.failures.fetch_add(1);
    if (static_cast<int>(job.deliveries) < consumer_.max_deliver) {
      say(fmt::format("failed {} (delivery {} of {}): {}", job.scan_id, job.deliveries, consumer_.max_deliver,
                      failure));
      settle();
      natsMsg_NakWithDelay(m, 500, nullptr);
      return;
    }
    const std::string reason = fmt::format("failed {} time(s); last: {}", job.deliveries, failure);
    const std::string scanner = job.scanner_id.empty() ? "unknown" : job.scanner_id;
    const std::string id =
        job.scan_id.empty() ? fmt::format("unnamed-{}", nats_NowInNanoSeconds()) : job.scan_id;
    bool duplicate = false;
    const std::string body(reinterpret_cast<const char*>(image.data()), image.size());
    if (publish_retrying(dead_subject(scanner).c_str(), id, body,
                         {{kHeaderScanId, id},
                          {kHeaderScanner, scanner},
                          {kHeaderReason, reason},
                          {"Facetscan-Worker", options_.worker_id}},
                         kDeadStream, stop, duplicate)) {
      settle();
      if (term_sync(m)) purge_parts(job);
      counters_.dead.fetch_add(1);
      say(fmt::format("dead-lettered {}: {}", id, reason));
    }
    return;
  }

  result["scan_id"] = job.scan_id;
  result["scanner_id"] = job.scanner_id;
  if (!job.status.empty()) result["scan_status"] = job.status;
  result["library"] = {
      {"id", options_.library_id}, {"hash", options_.library_hash}, {"models", library_.models.size()}};
  result["worker"] = {{"id", options_.worker_id}, {"delivery", job.deliveries}};
  if (job.streamed()) {
    // taken_before_end: the worker had the scan before its end reached the broker (it read it as it came).
    result["stream"] = {{"parts", job.next_part},
                        {"bytes", image.size()},
                        {"taken_before_end", job.taken_ns < job.last_stored_ns}};
    result["timings"]["last_part_ms"] = job.last_part_wait_ms;
  }
  result["timings"].update({{"queued_ms", queued_ms},
                            {"load_ms", load_ms},
                            {"recognize_ms", recognize_ms},
                            {"worker_ms", ms_since(t0)}});
  bool duplicate = false;
  const std::string body = result.dump();
  if (!publish_retrying(results_subject(job.scanner_id).c_str(), job.scan_id, body,
                        {{kHeaderScanId, job.scan_id}, {kHeaderScanner, job.scanner_id}}, kResultsStream,
                        stop, duplicate))
    return;  // not stored: not acked, redelivered
  jsErrCode err = static_cast<jsErrCode>(0);
  settle();
  const natsStatus st = natsMsg_AckSync(m, nullptr, &err);
  if (st == NATS_OK) purge_parts(job);  // else it may be redelivered: its parts stay
  if (job.streamed()) counters_.streamed.fetch_add(1);
  if (duplicate)
    counters_.duplicates.fetch_add(1);
  else
    counters_.results.fetch_add(1);
  say(fmt::format("{} {}: {} object(s), {:.0f} ms{}{}", duplicate ? "already had a result for" : "result",
                  job.scan_id, result["objects"].size(), ms_since(t0),
                  duplicate ? " (duplicate not stored)" : "",
                  st == NATS_OK ? "" : " (ack not confirmed: " + std::string(natsStatus_GetText(st)) + ")"));
}

void Worker::on_advisory(natsConnection*, natsSubscription*, natsMsg* msg, void* closure) {
  auto* self = static_cast<Worker*>(closure);
  try {
    self->dead_letter_after_advisory(msg);
  } catch (const std::exception& e) {
    self->say(std::string("dead letter after MAX_DELIVERIES advisory: ") + e.what());
  }
  natsMsg_Destroy(msg);
}

void Worker::dead_letter_after_advisory(natsMsg* advisory) {
  const nlohmann::json a = nlohmann::json::parse(
      std::string(natsMsg_GetData(advisory), static_cast<std::size_t>(natsMsg_GetDataLength(advisory))));
  const std::uint64_t seq = a.at("stream_seq").get<std::uint64_t>();
  const std::uint64_t deliveries = a.value("deliveries", std::uint64_t(0));
  natsMsg* m = nullptr;
  jsErrCode err = static_cast<jsErrCode>(0);
  natsStatus st = js_GetMsg(&m, connection_.js(), kScansStream, seq, nullptr, &err);
  if (st != NATS_OK) return;  // acked meanwhile, or another worker moved it
  const std::string scanner = scanner_of_subject(natsMsg_GetSubject(m), kScansPrefix);
  std::string id = nats_header(m, kHeaderScanId);
  if (id.empty()) id = fmt::format("seq-{}", seq);
  const std::string reason = fmt::format(
      "delivered {} time(s) without an acknowledgement (a worker died on it or exceeded AckWait {} ms)",
      deliveries, consumer_.ack_wait_ms);
  const std::string body(natsMsg_GetData(m), static_cast<std::size_t>(natsMsg_GetDataLength(m)));
  const std::string parts = nats_header(m, kHeaderParts);  // a streamed scan: its parts stay in PARTS
  natsMsg_Destroy(m);
  std::atomic<bool> never{false};
  bool duplicate = false;
  if (!publish_retrying(dead_subject(scanner.empty() ? "unknown" : scanner).c_str(), id, body,
                        {{kHeaderScanId, id},
                         {kHeaderScanner, scanner},
                         {kHeaderReason, reason},
                         {kHeaderParts, parts},
                         {"Facetscan-Worker", options_.worker_id}},
                        kDeadStream, never, duplicate))
    return;
  js_DeleteMsg(connection_.js(), kScansStream, seq, nullptr, &err);
  counters_.dead.fetch_add(1);
  say(fmt::format("dead-lettered {}: {}", id, reason));
}

}  // namespace fs::host::fleet
