#pragma once
// A recognition worker of the fleet (`facetscan worker`): pulls scans from the durable consumer "workers" on
// SCANS that every worker shares, recognizes each .fscan image exactly as `facetscan recognize x.fscan` does
// (host/io/scan_bytes.hpp), publishes the result to RESULTS (subject facetscan.results.<scanner-id>, message
// id = the scan's id) and only then acks the scan. docs/fleet.md#worker has the delivery rules:
//  * at most `threads` scans in flight per worker (one pull subscription per thread, batch 1); a scan being
//    recognized is marked in progress every AckWait/3, so only a dead or stuck worker's scans are
//    redelivered;
//  * a redelivered scan whose result was already stored yields no second result (RESULTS de-duplicates by
//    message id: the publish acknowledgement says "duplicate" and the scan is acked);
//  * a scan that fails (unreadable, triangulation or recognition error) is nak'ed and retried by any worker;
//    at its MaxDeliver-th failure it goes to DEAD (facetscan.dead.<scanner-id>, the .fscan image with the
//    reason in a header) and is terminated. A scan whose deliveries all timed out (the workers died on it) is
//    moved to DEAD by whichever worker receives the server's MAX_DELIVERIES advisory.
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "host/fleet/nats_connection.hpp"
#include "host/fleet/streams.hpp"
#include "host/io/scan.hpp"
#include "host/library/library.hpp"
#include "host/recognize/recognizer.hpp"

namespace fs::host::fleet {

struct WorkerOptions {
  std::string worker_id;     // in every result; default "<hostname>-<pid>"
  int threads = 1;           // scans recognized at once (bounded in-flight)
  std::string library_id;    // in every result: the library's file name(s)
  std::string library_hash;  // in every result: CRC-32C of the .fslib bytes (hex)
  rec::RecognizeParams params;
  ScanLimits limits;
  FleetSettings settings;  // applied when this worker creates missing streams / the consumer
  int test_hold_ms = 0;    // tests: hold each scan this long (marked in progress) before recognizing it
  std::function<void(const std::string&)> log;  // one line per event (thread-safe calls)
};

struct WorkerCounters {
  std::atomic<std::uint64_t> results{0};     // results stored
  std::atomic<std::uint64_t> duplicates{0};  // results the stream already held (a redelivery)
  std::atomic<std::uint64_t> failures{0};    // failed attempts (nak'ed or dead-lettered)
  std::atomic<std::uint64_t> dead{0};        // scans this worker moved to DEAD
};

class Worker {
 public:
  // Checks (or creates) the streams and the consumer; throws fs::Error when they are unusable.
  Worker(NatsConnection& connection, const Library& library, WorkerOptions options);
  ~Worker();
  Worker(const Worker&) = delete;
  Worker& operator=(const Worker&) = delete;

  // Runs the threads until `stop` is set; the scans in progress are finished (or nak'ed while held).
  void run(const std::atomic<bool>& stop);

  const WorkerCounters& counters() const { return counters_; }
  const ConsumerSettings& consumer() const { return consumer_; }

  struct Job;  // one delivered scan (worker.cpp)

 private:
  void thread_main(int index, const std::atomic<bool>& stop);
  void process(Job& job, const std::atomic<bool>& stop, std::unique_ptr<rec::Recognizer>& recognizer,
               std::size_t& recognizer_cells);
  bool publish_retrying(const char* subject, const std::string& msg_id, const std::string& body,
                        const std::vector<std::pair<std::string, std::string>>& headers, const char* stream,
                        const std::atomic<bool>& stop, bool& duplicate);
  static void on_advisory(natsConnection* nc, natsSubscription* sub, natsMsg* msg, void* closure);
  void dead_letter_after_advisory(natsMsg* advisory);
  void say(const std::string& line);

  NatsConnection& connection_;
  const Library& library_;
  WorkerOptions options_;
  ConsumerSettings consumer_;
  WorkerCounters counters_;
  natsSubscription* advisory_sub_ = nullptr;
  std::mutex log_mutex_;
};

// "<hostname>-<pid>".
std::string default_worker_id();

}  // namespace fs::host::fleet
