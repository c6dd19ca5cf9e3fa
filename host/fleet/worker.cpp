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

std::string header(natsMsg* m, const char* key) {
  const char* v = nullptr;
  if (natsMsgHeader_Get(m, key, &v) != NATS_OK || v == nullptr) return {};
  return v;
}

bool transient(natsStatus st) {
  return st == NATS_TIMEOUT || st == NATS_CONNECTION_DISCONNECTED || st == NATS_NO_RESPONDERS;
}

// Marks a message in progress every `period` until stopped (the scan's AckWait restarts each time).
class InProgressTicker {
 public:
  InProgressTicker(natsMsg* m, std::chrono::milliseconds period)
      : thread_([this, m, period] {
          std::unique_lock lock(mutex_);
          while (!cv_.wait_for(lock, period, [this] { return done_; })) natsMsg_InProgress(m, nullptr);
        }) {}
  ~InProgressTicker() { stop(); }
  void stop() {
    {
      std::lock_guard lock(mutex_);
      done_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  bool done_ = false;
  std::thread thread_;
};

}  // namespace

struct Worker::Job {
  natsMsg* msg = nullptr;
  std::string scan_id;
  std::string scanner_id;
  std::string status;
  std::uint64_t deliveries = 1;
  std::int64_t stored_ns = 0;  // when the stream stored the scan (UTC)
};

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

Worker::~Worker() {
  if (advisory_sub_ != nullptr) {
    natsSubscription_Unsubscribe(advisory_sub_);
    natsSubscription_Destroy(advisory_sub_);
  }
}

void Worker::say(const std::string& line) {
  if (!options_.log) return;
  std::lock_guard lock(log_mutex_);
  options_.log(fmt::format("worker {}: {}", options_.worker_id, line));
}

void Worker::run(const std::atomic<bool>& stop) {
  say(fmt::format("ready ({} thread(s), AckWait {} ms, MaxDeliver {}, library {} {})", options_.threads,
                  consumer_.ack_wait_ms, consumer_.max_deliver, options_.library_id, options_.library_hash));
  std::vector<std::thread> threads;
  for (int i = 0; i < options_.threads; ++i) threads.emplace_back([this, i, &stop] { thread_main(i, stop); });
  for (auto& t : threads) t.join();
  say(fmt::format("stopped: {} result(s), {} duplicate(s), {} failure(s), {} dead-lettered",
                  counters_.results.load(), counters_.duplicates.load(), counters_.failures.load(),
                  counters_.dead.load()));
}

void Worker::thread_main(int index, const std::atomic<bool>& stop) {
  std::unique_ptr<rec::Recognizer> recognizer;
  std::size_t recognizer_cells = 0;
  natsSubscription* sub = nullptr;
  int errors = 0;
  const std::string subject = std::string(kScansPrefix) + ">";
  while (!stop.load()) {
    if (sub == nullptr) {
      jsSubOptions so;
      jsSubOptions_Init(&so);
      so.Stream = kScansStream;
      so.Consumer = kWorkersConsumer;
      jsErrCode err = static_cast<jsErrCode>(0);
      const natsStatus st =
          js_PullSubscribe(&sub, connection_.js(), subject.c_str(), kWorkersConsumer, nullptr, &so, &err);
      if (st != NATS_OK) {
        sub = nullptr;
        if (errors++ % 20 == 0)
          say(nats_error_text(st, fmt::format("thread {}: pull subscribe", index), err));
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
      if (errors++ % 20 == 0) say(nats_error_text(st, fmt::format("thread {}: fetch", index), err));
      if (errors % 10 == 0) {
        natsSubscription_Destroy(sub);
        sub = nullptr;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
      continue;
    }
    errors = 0;
    for (int i = 0; i < list.Count; ++i) {
      Job job;
      job.msg = list.Msgs[i];
      process(job, stop, recognizer, recognizer_cells);
    }
    natsMsgList_Destroy(&list);
  }
  if (sub != nullptr) natsSubscription_Destroy(sub);
}

bool Worker::publish_retrying(const char* subject, const std::string& msg_id, const std::string& body,
                              const std::vector<std::pair<std::string, std::string>>& headers,
                              const char* stream, const std::atomic<bool>& stop, bool& duplicate) {
  for (int attempt = 0;; ++attempt) {
    natsMsg* m = nullptr;
    natsStatus st = natsMsg_Create(&m, subject, nullptr, body.data(), static_cast<int>(body.size()));
    if (st != NATS_OK) throw_nats(st, "result message");
    for (const auto& [k, v] : headers) natsMsgHeader_Set(m, k.c_str(), v.c_str());
    jsPubOptions po;
    jsPubOptions_Init(&po);
    po.MsgId = msg_id.c_str();
    po.ExpectStream = stream;
    jsPubAck* ack = nullptr;
    jsErrCode err = static_cast<jsErrCode>(0);
    st = js_PublishMsg(&ack, connection_.js(), m, &po, &err);
    natsMsg_Destroy(m);
    if (st == NATS_OK) {
      duplicate = ack->Duplicate;
      jsPubAck_Destroy(ack);
      return true;
    }
    if (attempt % 20 == 0) say(nats_error_text(st, fmt::format("publish {} to {}", msg_id, subject), err));
    // Not stored: keep trying while the server is away; on stop the scan stays unacked (redelivered).
    if (stop.load() || (!transient(st) && attempt >= 3)) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
}

void Worker::process(Job& job, const std::atomic<bool>& stop, std::unique_ptr<rec::Recognizer>& recognizer,
                     std::size_t& recognizer_cells) {
  const auto t0 = Clock::now();
  natsMsg* m = job.msg;
  jsMsgMetaData* meta = nullptr;
  if (natsMsg_GetMetaData(&meta, m) == NATS_OK) {
    job.deliveries = meta->NumDelivered;
    job.stored_ns = meta->Timestamp;
    jsMsgMetaData_Destroy(meta);
  }
  job.scanner_id = scanner_of_subject(natsMsg_GetSubject(m), kScansPrefix);
  job.scan_id = header(m, kHeaderScanId);
  job.status = header(m, kHeaderStatus);
  const std::span<const std::uint8_t> image(reinterpret_cast<const std::uint8_t*>(natsMsg_GetData(m)),
                                            static_cast<std::size_t>(natsMsg_GetDataLength(m)));
  const double queued_ms =
      job.stored_ns > 0 ? static_cast<double>(nats_NowInNanoSeconds() - job.stored_ns) / 1e6 : 0.0;
  say(fmt::format("recognizing {} (delivery {})", job.scan_id.empty() ? "?" : job.scan_id, job.deliveries));

  InProgressTicker ticker(m,
                          std::chrono::milliseconds(std::max<std::int64_t>(consumer_.ack_wait_ms / 3, 50)));
  if (options_.test_hold_ms > 0) {
    const auto until = Clock::now() + std::chrono::milliseconds(options_.test_hold_ms);
    while (Clock::now() < until && !stop.load()) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (stop.load()) {
      ticker.stop();
      natsMsg_Nak(m, nullptr);  // stopping: another worker takes it now
      return;
    }
  }

  nlohmann::json result;
  std::string failure;
  double load_ms = 0.0, recognize_ms = 0.0;
  try {
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
  ticker.stop();

  if (!failure.empty()) {
    counters_.failures.fetch_add(1);
    if (static_cast<int>(job.deliveries) < consumer_.max_deliver) {
      say(fmt::format("failed {} (delivery {} of {}): {}", job.scan_id, job.deliveries, consumer_.max_deliver,
                      failure));
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
      natsMsg_Term(m, nullptr);
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
  result["timings"] = {{"queued_ms", queued_ms},
                       {"load_ms", load_ms},
                       {"recognize_ms", recognize_ms},
                       {"worker_ms", ms_since(t0)}};
  bool duplicate = false;
  const std::string body = result.dump();
  if (!publish_retrying(results_subject(job.scanner_id).c_str(), job.scan_id, body,
                        {{kHeaderScanId, job.scan_id}, {kHeaderScanner, job.scanner_id}}, kResultsStream,
                        stop, duplicate))
    return;  // not stored: not acked, redelivered
  jsErrCode err = static_cast<jsErrCode>(0);
  const natsStatus st = natsMsg_AckSync(m, nullptr, &err);
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
  std::string id = header(m, kHeaderScanId);
  if (id.empty()) id = fmt::format("seq-{}", seq);
  const std::string reason = fmt::format(
      "delivered {} time(s) without an acknowledgement (a worker died on it or exceeded AckWait {} ms)",
      deliveries, consumer_.ack_wait_ms);
  const std::string body(natsMsg_GetData(m), static_cast<std::size_t>(natsMsg_GetDataLength(m)));
  natsMsg_Destroy(m);
  std::atomic<bool> never{false};
  bool duplicate = false;
  if (!publish_retrying(dead_subject(scanner.empty() ? "unknown" : scanner).c_str(), id, body,
                        {{kHeaderScanId, id},
                         {kHeaderScanner, scanner},
                         {kHeaderReason, reason},
                         {"Facetscan-Worker", options_.worker_id}},
                        kDeadStream, never, duplicate))
    return;
  js_DeleteMsg(connection_.js(), kScansStream, seq, nullptr, &err);
  counters_.dead.fetch_add(1);
  say(fmt::format("dead-lettered {}: {}", id, reason));
}

}  // namespace fs::host::fleet
