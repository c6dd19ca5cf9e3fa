#pragma once
// A recognition worker of the fleet (`facetscan worker`): pulls scans from the durable consumer "workers" on
// SCANS that every worker shares, recognizes each .fscan image exactly as `facetscan recognize x.fscan` does
// (host/io/scan_bytes.hpp), publishes the result to RESULTS (subject facetscan.results.<scanner-id>, message
// id = the scan's id) and only then acks the scan. docs/fleet.md#worker has the delivery rules:
//  * one thread fetches scans from the consumer, `threads` threads recognize them; a worker holds at most
//    `threads` + `max_streams` scans, and every scan it holds is marked in progress every AckWait/3, so only
//    a dead or stuck worker's scans are redelivered;
//  * a streamed scan (serve --nats --stream, scan_streamer.hpp) is taken at its ScanBegin: its parts are read
//    as they arrive (an ordered consumer on PARTS) and it is recognized when its last part is in; its parts
//    are purged once it is acked. A stream its gateway abandoned is dropped (the gateway sends the scan
//    whole); one whose parts stop for `part_timeout_ms` fails like an unreadable scan;
//  * a redelivered scan whose result was already stored yields no second result (RESULTS de-duplicates by
//    message id: the publish acknowledgement says "duplicate" and the scan is acked);
//  * a scan that fails (unreadable, triangulation or recognition error) is nak'ed and retried by any worker;
//    at its MaxDeliver-th failure it goes to DEAD (facetscan.dead.<scanner-id>, the .fscan image with the
//    reason in a header) and is terminated. A scan whose deliveries all timed out (the workers died on it) is
//    moved to DEAD by whichever worker receives the server's MAX_DELIVERIES advisory.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
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
  std::string worker_id;                 // in every result; default "<hostname>-<pid>"
  int threads = 1;                       // scans recognized at once
  int max_streams = 8;                   // streamed scans read at once besides those (bounded in-flight)
  std::int64_t part_timeout_ms = 60000;  // a streamed scan with no new part for this long fails
  std::string library_id;                // in every result: the library's file name(s)
  std::string library_hash;              // in every result: CRC-32C of the .fslib bytes (hex)
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
  std::atomic<std::uint64_t> streamed{0};    // of the results, scans read part by part
  std::atomic<std::uint64_t> abandoned{0};   // streamed scans their gateway abandoned (sent whole instead)
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
  void fetch_main(const std::atomic<bool>& stop);
  void recognize_main(const std::atomic<bool>& stop);
  void ticker_main(const std::atomic<bool>& stop);
  void take(std::unique_ptr<Job> job);     // a fetched scan: ready, or its parts are read first
  void ready(Job* job);                    // mu_ held: a collected scan goes to the recognizers
  void release(std::unique_ptr<Job> job);  // done with it (acked, nak'ed or terminated)
  static void on_part(natsConnection* nc, natsSubscription* sub, natsMsg* msg, void* closure);
  void process(Job& job, const std::atomic<bool>& stop, std::unique_ptr<rec::Recognizer>& recognizer,
               std::size_t& recognizer_cells);
  void purge_parts(const Job& job);
  bool term_sync(natsMsg* m);  // terminated, confirmed by the server
  struct PartClosure;
  static void free_part_closure(void* closure);
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

  std::mutex mu_;  // the scans held
  std::condition_variable ready_cv_, room_cv_;
  std::vector<Job*> held_;                                    // fetched, not released (marked in progress)
  std::deque<std::unique_ptr<Job>> ready_;                    // to recognize
  std::map<std::uint64_t, std::unique_ptr<Job>> collecting_;  // streamed scans whose parts are being read
  std::size_t recognizing_ = 0;
  std::uint64_t next_job_ = 1;
  std::vector<natsSubscription*> pull_subs_;  // every pull subscription made, ended by run() (mu_)

  std::mutex closures_mu_;  // the part subscriptions' closures still referenced by the client library
  std::condition_variable closures_cv_;
  int live_closures_ = 0;
  std::vector<std::unique_ptr<PartClosure>> orphan_closures_;
};

// "<hostname>-<pid>".
std::string default_worker_id();

}  // namespace fs::host::fleet
