#include "host/cli/live_commands.hpp"

#include <malloc.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include "common/byte_size.hpp"
#include "common/error.hpp"
#include "host/cli/fleet_demo.hpp"
#include "host/cli/fleet_submit.hpp"
#include "host/cli/install_paths.hpp"
#include "host/cli/memory_budget.hpp"
#include "host/cli/progress.hpp"
#include "host/fleet/gateway.hpp"
#include "host/io/scan.hpp"
#include "host/io/scan_limits.hpp"
#include "host/io/scan_writer.hpp"
#include "host/io/stream_server.hpp"
#include "host/io/triangulate.hpp"
#include "host/library/mesh_files.hpp"
#include "host/match/params.hpp"
#include "host/recognize/recognizer.hpp"
#include "host/recognize/report.hpp"
#include "host/web/http_server.hpp"
#include "host/web/report_view.hpp"

extern char** environ;

namespace fs::host::cli {
namespace {

namespace stdfs = std::filesystem;

// serve prints from two threads (the stream's notices, the processing thread's results): each message is
// written whole, then flushed (a log file or pipe sees it at once).
std::mutex g_out_mutex;
void emit(std::FILE* f, const std::string& text) {
  std::lock_guard lock(g_out_mutex);
  std::fputs(text.c_str(), f);
  std::fflush(f);
}

// The scanner's state for the web view (--http): sampled from the stream server by the serve / demo loop and
// published at most every 100 ms (and at once on a scan's start / end). Publishing never waits for a client.
class LiveTracker {
 public:
  LiveTracker(web::WebServer* web, const char* mode) : web_(web) { s_.mode = mode; }
  bool enabled() const { return web_ != nullptr; }

  void update(const StreamServer& server, bool force = false) {
    if (!web_) return;
    std::lock_guard lock(mu_);
    const auto now = std::chrono::steady_clock::now();
    const Scan& cur = server.current_scan();
    const bool scanning = cur.started() && cur.status() == ScanStatus::InProgress;
    if (!force && now - last_ < std::chrono::milliseconds(100) && scanning == s_.scanning) return;
    last_ = now;
    if (cur.started() && cur.scan_id() != s_.scan_id) samples_.clear();
    s_.connected = server.connected();
    s_.scanning = scanning;
    if (cur.started()) {
      s_.scan_id = cur.scan_id();
      s_.stripes = cur.stripes_received();
      s_.steps = cur.slot_count();
      s_.last_fault_code = cur.last_fault_code();
    }
    samples_.push_back({now, s_.stripes});
    while (samples_.size() > 2 && now - samples_[1].first >= std::chrono::seconds(1)) samples_.pop_front();
    const double dt = std::chrono::duration<double>(now - samples_.front().first).count();
    s_.stripes_per_s = scanning && dt > 0.05 ? (s_.stripes - samples_.front().second) / dt : 0.0;
    s_.faults = server.assembler_stats().faults;
    const StreamServerStats& st = server.stats();
    s_.connections = st.connections;
    s_.disconnects = st.disconnects;
    s_.protocol_errors = st.protocol_errors;
    s_.frames = st.frames;
    web_->publish_status(s_);
  }
  // A scan was delivered and is being recognized / was recognized.
  void recognizing(const Scan& scan, bool on) {
    if (!web_) return;
    std::lock_guard lock(mu_);
    s_.recognizing = on;
    s_.scanning = false;
    s_.scan_id = scan.scan_id();
    s_.stripes = scan.stripes_received();
    s_.steps = scan.slot_count();
    if (!on) ++s_.scans;
    if (scan.has_end()) {
      s_.has_loop = true;
      s_.loop = scan.end_message().loop;
    }
    web_->publish_status(s_);
  }

 private:
  web::WebServer* web_;
  std::mutex mu_;  // serve: update() in the stream's thread, recognizing() in the processing thread
  web::LiveStatus s_;
  std::chrono::steady_clock::time_point last_{};
  std::deque<std::pair<std::chrono::steady_clock::time_point, std::uint32_t>> samples_;
};

// What serve and demo do with scans besides recognizing them.
struct HandlerOptions {
  ScanLimits limits;         // the memory budget: the triangulator refuses a camera / grid beyond it
  bool keep_scans = false;   // scan.fscan in every scan's folder (failed scans always get one)
  WorkingSize working_size;  // storage kept warm; a larger scan's memory is returned after it
};

// Recognizes scans as they are delivered: triangulation -> recognition -> table, JSON and report (and the
// web view's record of the scan with --http). serve runs it in its processing thread (ScanJobs), demo in the
// stream's thread.
class ScanHandler {
 public:
  ScanHandler(const Library& library, rec::RecognizeParams params, std::string out_dir, bool quiet,
              HandlerOptions options = {})
      : library_(library),
        params_(std::move(params)),
        out_dir_(std::move(out_dir)),
        quiet_(quiet),
        options_(std::move(options)) {
    topt_.limits = options_.limits;
  }

  // Called before a scan's result is printed (the demo ends its progress bar there).
  void set_before_result(std::function<void(const Scan&)> f) { before_result_ = std::move(f); }
  // --http: the web server that gets every scan's record, the live state tracker, the recording's path.
  void set_web(web::WebServer* w, LiveTracker* tracker, std::string recording = {}) {
    web_ = w;
    tracker_ = tracker;
    recording_ = std::move(recording);
  }
  // Test hook (serve --test-pause-file): before processing a scan, wait while this file exists.
  void set_pause_file(std::string path) { pause_file_ = std::move(path); }
  // Recognition times of the scans so far (ms), for measurements.
  const std::vector<double>& recognition_ms() const { return recognition_ms_; }

  // Every scan delivered ends in exactly one result: recognized, or failed (a calibration the triangulation
  // refuses, a scene the matcher cannot take, ...) with the reason logged and written to result.json, and
  // the scan kept as scan.fscan beside it.
  void operator()(const Scan& scan) {
    ++scans_;
    pause_for_test(scan.scan_id());
    try {
      if (before_result_) before_result_(scan);
      if (tracker_) tracker_->recognizing(scan, true);
      if (options_.keep_scans && !out_dir_.empty()) keep_scan(scan);
      process(scan);
    } catch (const std::exception& e) {
      fail(scan, e.what());
    }
    if (tracker_) tracker_->recognizing(scan, false);
  }
  // serve's processing thread: a queued job. A ScanBegin the limits refused is a failed result; with
  // `stopping` (serve is shutting down) a scan is not recognized but written as a failed "server stopped"
  // result with its scan.fscan, to be recognized offline.
  void operator()(const ScanJob& job, bool stopping) {
    if (!job.scan) {
      refused(job);
    } else if (stopping) {
      ++scans_;
      ++stopped_;
      fail(*job.scan,
           "server stopped before the scan was processed (its scan.fscan can be recognized offline)");
    } else {
      (*this)(*job.scan);
    }
  }
  // After a scan larger than the working size: frees the cloud, the triangulator's tables, the recognizer
  // and `scan`'s storage beyond the working size, and returns the pages to the system (malloc_trim).
  // Returns the bytes freed (0 after a normal scan: nothing is freed or reallocated).
  std::uint64_t release_memory(Scan& scan) {
    const WorkingSize& w = options_.working_size;
    const std::uint64_t cells = std::uint64_t(w.steps) * w.rows;
    std::uint64_t freed = 0;
    if (recognizer_ && recognizer_cells_ > cells) {
      freed += ScanLimits::recognizer_bytes(recognizer_cells_, options_.limits.threads,
                                            options_.limits.segment_row_step);
      recognizer_.reset();
      recognizer_cells_ = 0;
    }
    const std::uint64_t rest = release_scan_memory(scan, triangulator_, &cloud_, w);
    if (freed > 0 && rest == 0) malloc_trim(0);
    return freed + rest;
  }
  int scans() const { return scans_; }
  int failed() const { return failed_; }
  int refused_count() const { return refused_; }
  int stopped() const { return stopped_; }
  // A scan that could not be handled elsewhere (the gateway could not spool it): a failed result with its
  // scan.fscan kept.
  void failed(const Scan& scan, const std::string& reason) {
    ++scans_;
    fail(scan, reason);
  }
  // Stripe points triangulated but not kept in the depth map (another point of the stripe in the same row).
  std::uint64_t shared_cell_points() const { return shared_cell_; }
  int last_objects() const { return last_objects_; }
  const stdfs::path& last_dir() const { return last_dir_; }

 private:
  // The "scan" object of a result.json, recognized or failed.
  static nlohmann::json scan_json(const Scan& scan) {
    return {{"scan_id", scan.scan_id()},
            {"status", to_string(scan.status())},
            {"partial", !scan.complete()},
            {"stripes", scan.stripes_received()},
            {"steps", scan.slot_count()}};
  }

  stdfs::path scan_dir(std::uint64_t scan_id) const {
    return stdfs::path(out_dir_) / fmt::format("scan-{:03}-id{}", scans_.load(), scan_id);
  }

  void pause_for_test(std::uint64_t scan_id) const {
    if (pause_file_.empty() || !stdfs::exists(pause_file_)) return;
    emit(stdout, fmt::format("test: processing of scan {} paused while {} exists\n", scan_id, pause_file_));
    while (stdfs::exists(pause_file_)) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }

  void keep_scan(const Scan& scan) {
    const stdfs::path dir = scan_dir(scan.scan_id());
    stdfs::create_directories(dir);
    write_scan_file(dir / "scan.fscan", scan);
  }

  // A failed result: "scan N (...): FAILED: reason" on stdout (also with -q), and in the scan's folder
  // {"failed": true, "error": reason, "scan": {...}} as result.json and the scan as scan.fscan.
  void write_failed(std::uint64_t scan_id, const std::string& head, const std::string& reason,
                    const nlohmann::json& scan, const std::function<void(const stdfs::path&)>& write_fscan) {
    ++failed_;
    last_objects_ = -1;
    std::string text = fmt::format("\n{}: FAILED: {}\n", head, reason);
    if (!out_dir_.empty()) {
      const stdfs::path dir = scan_dir(scan_id);
      try {
        stdfs::create_directories(dir);
        const nlohmann::json j = {{"failed", true}, {"error", reason}, {"scan", scan}};
        std::ofstream f(dir / "result.json");
        f << j.dump(2) << "\n";
        if (!f) throw Error((dir / "result.json").string() + ": cannot write");
        last_dir_ = dir;
        text += fmt::format("result: {}\n", (dir / "result.json").string());
        write_fscan(dir / "scan.fscan");
        text += fmt::format("scan kept: {}\n", (dir / "scan.fscan").string());
      } catch (const std::exception& e) {
        text += fmt::format("facetscan: scan {}: cannot write the failed result: {}\n", scan_id, e.what());
      }
    }
    emit(stdout, text);
  }

  void fail(const Scan& scan, const std::string& reason) {
    write_failed(scan.scan_id(),
                 fmt::format("scan {} ({} of {} stripes{})", scan.scan_id(), scan.stripes_received(),
                             scan.slot_count(),
                             scan.complete() ? "" : fmt::format(", PARTIAL: {}", to_string(scan.status()))),
                 reason, scan_json(scan), [&](const stdfs::path& p) { write_scan_file(p, scan); });
  }

  // A ScanBegin the limits refused (the memory budget): one failed result; its .fscan holds the ScanBegin.
  void refused(const ScanJob& job) {
    ++scans_;
    ++refused_;
    const msg::ScanBegin& b = job.refused_begin;
    const nlohmann::json scan = {
        {"scan_id", b.scan_id}, {"status", "refused at ScanBegin"},  {"partial", true},
        {"stripes", 0},         {"steps", b.calibration.step_count}, {"peer", job.peer}};
    write_failed(b.scan_id, fmt::format("scan {} from {} (REFUSED at ScanBegin)", b.scan_id, job.peer),
                 job.refusal, scan, [&](const stdfs::path& p) { write_scan_file(p, b); });
  }

  void process(const Scan& scan) {
    const bool partial = !scan.complete();
    if (!triangulator_.configured()) triangulator_.configure(scan.begin_message().calibration, topt_);
    const TriangulationStats ts = triangulator_.triangulate(scan, cloud_);
    shared_cell_ += ts.shared_cell;
    if (!recognizer_ || recognizer_cells_ < cloud_.points.size()) {
      recognizer_.reset();  // the old one's memory goes before the new one's comes
      recognizer_ = std::make_unique<rec::Recognizer>(library_, params_, cloud_.points.size());
      recognizer_cells_ = cloud_.points.size();
    }
    const Plane table = scan.begin_message().calibration.table;
    const rec::Recognition& r = recognizer_->recognize(cloud_, &table);
    const auto result_time = std::chrono::system_clock::now();
    last_objects_ = static_cast<int>(r.objects.size());
    recognition_ms_.push_back(r.stats.total_ms);
    std::string text;
    if (!quiet_) {
      text += fmt::format("\nscan {} ({} of {} stripes{}): {} object(s)\n", scan.scan_id(),
                          scan.stripes_received(), scan.slot_count(),
                          partial ? fmt::format(", PARTIAL: {}", to_string(scan.status())) : "",
                          r.objects.size());
      text += rec::result_table(r, library_);
      text +=
          fmt::format("recognition: {:.0f} ms (segmentation {:.0f}, matching {:.0f}, verification {:.0f})\n",
                      r.stats.total_ms, r.stats.segment_ms, r.stats.match_ms, r.stats.verify_ms);
    }
    // The web view first (its 3D view needs no report), then again with the report's links once it exists.
    web::ScanInfo info;
    std::shared_ptr<web::ScanRecord> published;  // the first record: its points serve the second one too
    if (web_) {
      info.id = static_cast<std::uint64_t>(scans_.load());
      info.scan_id = scan.scan_id();
      info.title = fmt::format("scan {}", scan.scan_id());
      info.status = to_string(scan.status());
      info.partial = partial;
      info.stripes = scan.stripes_received();
      info.steps = scan.slot_count();
      info.result_unix_ms =
          std::chrono::duration_cast<std::chrono::milliseconds>(result_time.time_since_epoch()).count();
      info.has_recording = !recording_.empty();
      published = web::make_record(info, cloud_, *recognizer_, r, &table);
      published->recording = recording_;
      web_->publish_scan(published);
    }
    if (!out_dir_.empty()) {
      const stdfs::path dir = scan_dir(scan.scan_id());
      web::write_report(dir / "report", fmt::format("scan {}", scan.scan_id()), cloud_, *recognizer_, r,
                        &table);
      nlohmann::json j = rec::to_json(r, library_);
      j["scan"] = scan_json(scan);
      std::ofstream(dir / "result.json") << j.dump(2) << "\n";
      last_dir_ = dir;
      if (!quiet_) text += fmt::format("report: {}\n", (dir / "report" / "index.html").string());
      if (web_) {
        info.has_report = info.has_result = true;
        auto record = web::make_record(info, *published, cloud_, *recognizer_, r, &table);
        record->dir = dir;
        web_->publish_scan(std::move(record));
      }
    }
    if (!text.empty()) emit(stdout, text);
  }

  const Library& library_;
  rec::RecognizeParams params_;
  std::string out_dir_;
  bool quiet_;
  HandlerOptions options_;
  TriangulationOptions topt_;
  Triangulator triangulator_;
  OrganizedCloud cloud_;
  std::unique_ptr<rec::Recognizer> recognizer_;
  std::size_t recognizer_cells_ = 0;
  std::function<void(const Scan&)> before_result_;
  web::WebServer* web_ = nullptr;
  LiveTracker* tracker_ = nullptr;
  std::string recording_;
  std::string pause_file_;
  std::vector<double> recognition_ms_;
  // Read by serve's stream thread (--max-scans, the summary) while the processing thread counts.
  std::atomic<int> scans_{0}, failed_{0}, refused_{0}, stopped_{0};
  std::uint64_t shared_cell_ = 0;
  int last_objects_ = -1;
  stdfs::path last_dir_;
};

std::atomic<StreamServer*> g_server{nullptr};
std::atomic<bool> g_signalled{false};
// SIGINT / SIGTERM: the first stops the stream server's loop (serve then shuts down in order), a second one
// exits at once (async-signal-safe: _exit).
extern "C" void on_signal(int sig) {
  if (g_signalled.exchange(true)) ::_exit(128 + sig);
  if (StreamServer* s = g_server.load()) s->stop();
}

// --http and its limits (serve and demo).
struct WebCliOptions {
  std::string listen;  // empty = no web view
  std::size_t history = web::WebOptions{}.history;
  int max_clients = web::WebOptions{}.max_event_clients;
  int wait_s = 0;  // demo: wait up to this long for a page to connect before the scan starts
};

void add_web_options(CLI::App* cmd, WebCliOptions& w) {
  cmd->add_option("--http", w.listen,
                  "Serve the live web view (3D view, status, history, JSON API) on ADDR:PORT, e.g. "
                  "127.0.0.1:8080 (loopback unless you name another address; port 0 picks one)");
  cmd->add_option("--http-history", w.history, "Scans the web view keeps (memory bound)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  cmd->add_option("--http-clients", w.max_clients, "Open pages (event streams) the web view accepts")
      ->capture_default_str()
      ->check(CLI::Range(1, 256));
}

std::unique_ptr<web::WebServer> start_web(const WebCliOptions& w, bool quiet) {
  if (w.listen.empty()) return nullptr;
  web::WebOptions wo;
  wo.listen = w.listen;
  wo.history = w.history;
  wo.max_event_clients = w.max_clients;
  wo.threads = std::max(wo.threads, w.max_clients + 4);  // every open page holds a thread for its events
  auto server = std::make_unique<web::WebServer>(wo);
  server->start();
  if (!quiet) fmt::print("web view: {}\n", server->url());
  std::fflush(stdout);
  return server;
}

struct ServeOptions {
  std::string listen = "127.0.0.1:7450";
  std::vector<std::string> library;
  std::string out_dir;
  std::string params = "t9.3";
  int max_scans = 0;
  std::int64_t reconnect_grace_ms = StreamServerOptions{}.reconnect_grace_ms;
  std::string memory_budget;  // empty = the default budget (2 GiB)
  int segment_row_step = 1;   // RecognizeParams::segment_row_step
  int max_clients = StreamServerOptions{}.max_clients;
  bool keep_scans = false;
  std::string test_pause_file;  // hidden test hook, see ScanHandler::set_pause_file
  bool quiet = false;
  WebCliOptions web;
  // --nats: the gateway (docs/fleet.md#gateway) publishes every scan to the fleet instead of recognizing it.
  fleet::NatsOptions nats;
  std::string scanner;  // empty: one id per scanner address
  std::string spool_dir = "facetscan-spool";
  std::string spool_max = "2GiB";
  double drain_s = 5.0;
  bool stream = false;  // --stream: scans go into the fleet while they stream
  std::string part_size = "256KiB";
};

// The output folder, checked before anything listens or scans: created when missing; a path that is a file
// (or cannot be created or written) is refused naming it, instead of failing at the first scan.
void prepare_out_dir(const std::string& dir) {
  if (dir.empty()) return;
  std::error_code ec;
  stdfs::create_directories(dir, ec);
  if (stdfs::exists(dir) && !stdfs::is_directory(dir))
    throw Error(fmt::format("-o {}: not a directory", dir));
  if (!stdfs::is_directory(dir)) throw Error(fmt::format("-o {}: cannot create it ({})", dir, ec.message()));
  if (::access(dir.c_str(), W_OK) != 0)
    throw Error(fmt::format("-o {}: not writable ({})", dir, std::strerror(errno)));
}

// A malformed frame from the scanner (bad magic / CRC, oversize frame, absurd stripe): logged on stdout with
// the peer; serve closes that connection and goes on.
void log_protocol_error(const std::string& peer, const std::string& reason) {
  emit(stdout, fmt::format("facetscan serve: protocol error from {}: {}; connection closed\n", peer, reason));
}

void log_notice(const std::string& peer, const std::string& what) {
  emit(stdout, fmt::format("facetscan serve: {}: {}\n", peer, what));
}

// serve --nats: the gateway's options (docs/fleet.md#gateway).
void add_gateway_options(CLI::App* serve, ServeOptions& so) {
  const char* group = "Gateway (--nats: publish every scan to the fleet instead of recognizing it)";
  add_nats_options(serve, so.nats, false);
  serve
      ->add_option("--scanner", so.scanner,
                   "Scanner id of every scan (subject facetscan.scans.ID); default: one id per scanner "
                   "address, e.g. 10-0-3-17")
      ->group(group);
  serve
      ->add_option(
          "--spool", so.spool_dir,
          "Disk spool: every scan is kept here until the stream has stored it (also across restarts)")
      ->capture_default_str()
      ->group(group);
  serve
      ->add_option("--spool-max", so.spool_max,
                   "Spool bound; when full the scanners are held (TCP back-pressure), nothing is dropped")
      ->capture_default_str()
      ->group(group);
  serve
      ->add_flag("--stream", so.stream,
                 "Send each scan into the fleet while it streams, in parts, so that a worker has it when it "
                 "ends (docs/fleet.md#streamed-scans); a stream that fails goes whole through the spool")
      ->group(group);
  serve->add_option("--part-size", so.part_size, "--stream: bytes per part")
      ->capture_default_str()
      ->group(group);
  serve
      ->add_option("--nats-drain", so.drain_s,
                   "At exit, seconds to keep sending the spool (what is left is sent at the next start)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 3600.0))
      ->group(group);
}

// serve: the stream server's loop in this thread (accepting, reading, heartbeats, signals), recognition in a
// processing thread fed through a bounded queue. When the queue is full the stream server holds the frame
// that would deliver another scan (back-pressure, see stream_server.hpp). The queue takes at most 2 scans and
// at most a quarter of the memory budget of them (an empty queue always takes one).
void run_serve(const ServeOptions& o) {
  prepare_out_dir(o.out_dir);
  rec::RecognizeParams params;
  params.match = match::read_params(o.params);
  params.segment_row_step = o.segment_row_step;
  const ScanLimits limits = memory_budget_limits(o.memory_budget, params.threads, params.segment_row_step);
  const bool gateway_mode = !o.nats.url.empty();
  if (gateway_mode && !o.library.empty())
    throw Error(
        "serve --nats: --library is not used (the fleet's workers recognize: `facetscan worker -l ...`)");
  if (!gateway_mode && o.library.empty())
    throw Error("serve: --library is required (or --nats URL: the gateway)");
  if (!gateway_mode && o.stream) throw Error("serve: --stream needs --nats URL (the gateway)");
  const Library library = gateway_mode ? Library{} : load_or_build_library(o.library);
  std::unique_ptr<fleet::Gateway> gateway;
  if (gateway_mode) {
    fleet::GatewayOptions go;
    go.nats = o.nats;
    go.scanner_id = o.scanner;
    go.spool_dir = o.spool_dir;
    try {
      go.spool_max_bytes = parse_byte_size(o.spool_max);
    } catch (const Error& e) {
      throw Error(fmt::format("--spool-max: {}", e.what()));
    }
    go.stream = o.stream;
    try {
      const std::uint64_t part = parse_byte_size(o.part_size);
      // A part takes one more stripe frame than this: 4 MiB keeps it under the shipped max_payload (8 MB).
      if (part < 4096 || part > (std::uint64_t(4) << 20)) throw Error("from 4KiB to 4MiB");
      go.part_bytes = static_cast<std::size_t>(part);
    } catch (const Error& e) {
      throw Error(fmt::format("--part-size: {}", e.what()));
    }
    go.quiet = o.quiet;
    go.log = [](const std::string& line) { emit(stdout, "facetscan serve: " + line + "\n"); };
    gateway = std::make_unique<fleet::Gateway>(go);
  }
  HandlerOptions ho;
  ho.limits = limits;
  ho.keep_scans = o.keep_scans;
  ScanHandler handler(library, params, o.out_dir, o.quiet, ho);
  handler.set_pause_file(o.test_pause_file);
  const auto web = start_web(o.web, o.quiet);
  LiveTracker tracker(web.get(), "serve");
  if (web) handler.set_web(web.get(), &tracker);

  ScanQueue queue(2, limits.budget_bytes / 4);
  std::atomic<int> delivered{0};  // scans (and refused ScanBegins) handed to the processing thread
  std::atomic<int> processed{0};  // of them, done
  const auto taken_all = [&] { return o.max_scans > 0 && delivered.load() >= o.max_scans; };
  StreamServerOptions so;
  so.listen = o.listen;
  so.reconnect_grace_ms = o.reconnect_grace_ms;
  so.max_clients = o.max_clients;
  so.limits = limits;
  so.release_large_scans = true;
  so.on_protocol_error = log_protocol_error;
  so.on_notice = log_notice;
  so.can_deliver = [&] { return queue.has_room() && !taken_all(); };
  so.on_refused = [&](const std::string& peer, const msg::ScanBegin& begin, const std::string& reason) {
    ++delivered;
    ScanJob job;
    job.refused_begin = begin;
    job.refusal = reason;
    job.peer = peer;
    queue.push(std::move(job));
  };
  if (gateway)
    so.on_scan_frame = [&](const std::string& peer, const wire::DecodedMessage& m) {
      gateway->stream_frame(peer, m);
    };
  StreamServer* server_ptr = nullptr;
  StreamServer server(so, [&](const Scan& s) {
    const std::uint64_t stream = gateway ? gateway->stream_end(s, !taken_all()) : 0;
    if (taken_all()) {  // --max-scans reached: only the shutdown's partial scan can come here
      log_notice(server_ptr->peer(),
                 fmt::format("scan {} not taken (--max-scans {} reached)", s.scan_id(), o.max_scans));
      return;
    }
    const int ahead = delivered.load() - processed.load();  // being processed or queued
    ++delivered;
    ScanJob job;
    job.scan = std::make_unique<Scan>(s);  // the assembler reuses its Scan
    job.bytes = scan_copy_bytes(s);
    job.peer = server_ptr->peer();
    job.stream = stream;
    queue.push(std::move(job));
    if (ahead > 0 && !o.quiet)
      log_notice(server_ptr->peer(),
                 fmt::format("scan {} received, queued behind {} scan(s)", s.scan_id(), ahead));
  });
  server_ptr = &server;
  server.start();

  std::atomic<bool> stopping{false};
  std::thread worker([&] {
    ScanJob job;
    while (queue.pop(job)) {
      if (gateway && job.scan) {
        try {
          gateway->submit(*job.scan, job.peer, stopping.load(), job.stream);
        } catch (const std::exception& e) {
          handler.failed(*job.scan, fmt::format("the gateway could not spool the scan: {}", e.what()));
        }
      } else {
        handler(job, stopping.load());
      }
      Scan empty;
      handler.release_memory(job.scan ? *job.scan : empty);
      job = ScanJob{};
      ++processed;
      server.wake();  // the stream server may have held a frame for room in the queue
    }
  });

  g_server = &server;
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  if (!o.quiet)
    emit(stdout,
         fmt::format("facetscan serve: listening on {} (port {}), {}, memory budget {}, up to {} "
                     "connections; Ctrl-C stops\n",
                     o.listen, server.port(),
                     gateway ? fmt::format("gateway to {} (spool {}, at most {})", o.nats.url, o.spool_dir,
                                           format_byte_size(gateway->spool().max_bytes()))
                             : fmt::format("{} models", library.models.size()),
                     format_byte_size(limits.budget_bytes), o.max_clients));
  tracker.update(server, true);
  while (server.poll_once(200)) {
    tracker.update(server);
    if (taken_all()) break;
  }
  if (g_signalled) {
    // Stop listening at once; the scan in progress is delivered as partial; the scan being recognized is
    // finished (its work is bounded: the memory budget, the matcher's state budgets); what is queued is
    // written as failed "server stopped" results with its scan.fscan. A second signal exits at once.
    stopping = true;
    emit(stdout,
         fmt::format("facetscan serve: stopping: {} queued scan(s) and the scan in progress are written "
                     "as failed results (scan.fscan kept); the scan being recognized is finished (a "
                     "second signal exits at once)\n",
                     queue.size()));
  }
  server.close_all();
  queue.close();
  if (gateway) gateway->release_waiters();  // a scan waiting for room in a full spool is spooled now
  worker.join();
  if (web) web->stop();
  g_server = nullptr;
  if (gateway) {
    const std::size_t left =
        gateway->stop(std::chrono::milliseconds(static_cast<std::int64_t>(o.drain_s * 1000)));
    const fleet::GatewayStats gs = gateway->stats();
    std::string text =
        fmt::format("facetscan serve: gateway: {} scan(s) received, {} published", gs.received, gs.published);
    if (o.stream)
      text += fmt::format(" ({} streamed, {} stream(s) abandoned and sent whole)", gs.streamed,
                          gs.stream_failures);
    if (gs.duplicates > 0) text += fmt::format(", {} already stored", gs.duplicates);
    if (gs.outages > 0)
      text += fmt::format(", {} outage(s) of the server (spool peak {})", gs.outages,
                          format_byte_size(gs.spool_peak_bytes));
    if (left > 0)
      text += fmt::format("; {} scan(s) ({}) left in the spool {}, sent at the next start", left,
                          format_byte_size(gateway->spool().bytes()), gateway->spool().dir().string());
    if (gateway->spool().rejected() > 0)
      text += fmt::format("; {} scan(s) in {} (never publishable, see their .reason)",
                          gateway->spool().rejected(), (gateway->spool().dir() / "rejected").string());
    emit(stdout, text + "\n");
  }
  if (!o.quiet) {
    const StreamServerStats& st = server.stats();
    // Failures and protocol errors only when there were any: a clean run's summary stays as it was.
    std::string problems;
    if (handler.failed() > 0) problems += fmt::format(", {} failed", handler.failed());
    if (handler.stopped() > 0)
      problems += fmt::format(", {} not processed (server stopped)", handler.stopped());
    if (st.protocol_errors > 0)
      problems += fmt::format(", {} protocol error(s) (last: {})", st.protocol_errors, st.last_error);
    if (st.scan_errors > 0)
      problems += fmt::format(", {} scan error(s) (last: {})", st.scan_errors, st.last_scan_error);
    if (handler.refused_count() > 0)
      problems += fmt::format(", {} ScanBegin(s) refused (memory budget / limits)", handler.refused_count());
    if (st.refused_connections > 0)
      problems += fmt::format(", {} connection(s) refused", st.refused_connections);
    if (st.idle_closed > 0) problems += fmt::format(", {} idle connection(s) closed", st.idle_closed);
    if (st.waited_scans > 0)
      problems += fmt::format(", {} scan(s) waited for another scanner", st.waited_scans);
    if (st.resumed > 0) problems += fmt::format(", {} scan(s) resumed on a new connection", st.resumed);
    if (handler.shared_cell_points() > 0)
      problems += fmt::format(", {} stripe point(s) not in the depth map (a brighter point shared the cell)",
                              handler.shared_cell_points());
    emit(stdout, fmt::format("facetscan serve: {} scan(s), {} connection(s), {} disconnect(s){}\n",
                             gateway ? static_cast<int>(gateway->stats().received) + handler.scans()
                                     : handler.scans(),
                             st.connections, st.disconnects, problems));
    if (web)
      emit(stdout,
           fmt::format("recognition ms per scan: {:.1f}\n", fmt::join(handler.recognition_ms(), " ")));
  }
}

// The galvo twin of the demo, as facetscan-fw-hil's --galvo value:
//   gpio (or sim): the firmware's step/dir StepperGalvo driving the simulated GPIO lines (hw-sim
//   SimStepperLines); can (or sim-can[:node=N,...]): the firmware's CiA 402 master driving the simulated
//   drive (hw-sim Cia402Twin) with CAN frames over a socketpair.
// Real devices (gpio:CHIP:..., can:IFACE) are not a demo: facetscan-fw runs them on the board.
struct GalvoTwin {
  std::string fw_spec;
  const char* description;
};
GalvoTwin galvo_twin(const std::string& name) {
  if (name == "gpio" || name == "sim") return {"sim", "step/dir GPIO twin"};
  if (name == "can" || name == "sim-can") return {"sim-can", "CiA 402 drive twin on simulated CAN"};
  if (name.rfind("sim-can:", 0) == 0) return {name, "CiA 402 drive twin on simulated CAN"};
  throw Error("--galvo '" + name +
              "': the demo runs on a twin: gpio (step/dir on simulated GPIO lines) or can (CiA 402 drive on "
              "simulated CAN; sim-can:node=N,... passes drive settings); real devices are for facetscan-fw");
}

struct DemoOptions {
  std::string scene = "default";
  std::string galvo = "gpio";
  std::vector<std::string> faults;
  std::string out_dir = "demo-out";
  std::vector<std::string> library;
  int steps = 0;
  int timeout_s = 120;
  bool quiet = false;
  WebCliOptions web;
  int fleet = 0;  // --fleet N: the fleet demo (fleet_demo.hpp)
  int workers = 2;
  int fleet_scans = 1;
};

int run_demo(const DemoOptions& o) {
  stdfs::path scene = o.scene;
  if (!stdfs::exists(scene)) scene = scenes_dir() / (o.scene + ".json");
  if (!stdfs::exists(scene)) throw Error("--scene: no scene file or shipped scene named '" + o.scene + "'");
  const GalvoTwin twin = galvo_twin(o.galvo);
  for (const auto& f : o.faults)
    if (twin.fw_spec != "sim" && f.rfind("galvo.", 0) == 0)
      throw Error("--fault '" + f +
                  "': galvo faults act on the step/dir GPIO twin (--galvo gpio); the CAN twin "
                  "takes camera.* and laser.* faults");
  std::vector<std::string> lib_inputs = o.library;
  if (lib_inputs.empty()) lib_inputs.push_back((scene.parent_path() / "meshes").string());
  const Library library = load_or_build_library(lib_inputs);
  prepare_out_dir(o.out_dir);
  const std::string recording = (stdfs::path(o.out_dir) / "scan.fscan").string();

  ScanHandler handler(library, rec::RecognizeParams{}, o.out_dir, o.quiet);
  const auto web = start_web(o.web, o.quiet);
  LiveTracker tracker(web.get(), "demo");
  if (web) handler.set_web(web.get(), &tracker, recording);
  StreamServerOptions so;
  so.listen = "127.0.0.1:0";
  so.reconnect_grace_ms = 2000;
  StreamServer server(so, [&](const Scan& s) { handler(s); });
  server.start();
  if (web && o.web.wait_s > 0) {
    // Let a page connect first, so that it watches the whole scan (the browser test; a presenter).
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(o.web.wait_s);
    while (web->stats().event_clients == 0 && std::chrono::steady_clock::now() < until) {
      tracker.update(server);
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }

  // The firmware on the twins (the board binary facetscan-fw has no simulated devices).
  const stdfs::path fw = self_dir() / "facetscan-fw-hil";
  if (!stdfs::exists(fw)) throw Error(fw.string() + ": facetscan-fw-hil not found next to facetscan");
  std::vector<std::string> args = {fw.string(),    "--galvo",  twin.fw_spec,
                                   "--camera",     "sim",      "--scene",
                                   scene.string(), "--stream", fmt::format("127.0.0.1:{}", server.port()),
                                   "--record",     recording};
  if (o.steps > 0) args.insert(args.end(), {"--steps", std::to_string(o.steps)});
  for (const auto& f : o.faults) args.insert(args.end(), {"--fault", f});
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  if (!o.quiet) {
    fmt::print("facetscan demo: scene {} ({} models in the library), galvo: {}{}\nfirmware: {}\n",
               scene.filename().string(), library.models.size(), twin.description,
               o.faults.empty() ? "" : fmt::format(", injected fault(s): {}", fmt::join(o.faults, " ")),
               fmt::join(args, " "));
    std::fflush(stdout);
  }
  pid_t pid = -1;
  if (posix_spawn(&pid, argv[0], nullptr, nullptr, argv.data(), environ) != 0)
    throw Error(fw.string() + ": cannot start the firmware");

  // The number of steps of the scan, for the progress bar: --steps, else the scene's, else the default 500.
  std::size_t steps = o.steps > 0 ? static_cast<std::size_t>(o.steps) : 500;
  if (o.steps <= 0) {
    try {
      std::ifstream sf(scene);
      const nlohmann::json sj = nlohmann::json::parse(sf);
      if (sj.contains("scanner") && sj["scanner"].contains("steps"))
        steps = sj["scanner"]["steps"].get<std::size_t>();
    } catch (const std::exception&) {
    }
  }
  Progress progress(steps, o.quiet, 0.0);
  handler.set_before_result([&progress](const Scan& scan) {
    progress.update(scan.stripes_received(), "stripes received");  // the bar ends at what the scan holds
    progress.finish();
  });
  std::uint64_t shown = 0;
  const auto start = std::chrono::steady_clock::now();
  int status = 0;
  bool exited = false;
  while (handler.scans() == 0) {
    server.poll_once(50);
    tracker.update(server);
    const std::uint64_t frames = server.stats().frames;
    if (frames >= shown + 10 || (frames > shown && frames >= steps)) {
      shown = frames;
      progress.update(static_cast<std::size_t>(std::min<std::uint64_t>(frames, steps)), "stripes received");
    }
    if (!exited && waitpid(pid, &status, WNOHANG) == pid) exited = true;
    if (exited && !server.connected()) {
      // The firmware is gone; give the stream a moment, then deliver what arrived as partial.
      for (int i = 0; i < 10 && handler.scans() == 0; ++i) server.poll_once(50);
      if (handler.scans() == 0) server.close_all();
      break;
    }
    if (std::chrono::steady_clock::now() - start > std::chrono::seconds(o.timeout_s)) {
      kill(pid, SIGTERM);
      server.close_all();
      break;
    }
  }
  progress.finish();
  if (!exited) waitpid(pid, &status, 0);
  const int fw_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  if (!o.quiet) {
    fmt::print("firmware exit code {}; recording: {}\n", fw_code, recording);
    if (!handler.last_dir().empty())
      fmt::print("result: {}\n", (handler.last_dir() / "result.json").string());
  }
  if (web && handler.scans() > 0) {
    // The web view stays up to be looked at: until Ctrl-C / SIGTERM.
    if (!o.quiet) fmt::print("web view: {} (Ctrl-C stops)\n", web->url());
    std::fflush(stdout);
    g_server = &server;
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    tracker.update(server, true);
    while (server.poll_once(200)) tracker.update(server);
    g_server = nullptr;
    web->stop();
  }
  if (handler.scans() == 0)
    throw Error("the demo received no scan from facetscan-fw-hil (exit code " + std::to_string(fw_code) +
                ")");
  return fw_code;
}

}  // namespace

void add_live_commands(CLI::App& app) {
  auto so = std::make_shared<ServeOptions>();
  auto* serve = app.add_subcommand("serve", "Listen for scanners and recognize every scan they stream");
  serve->add_option("--listen", so->listen, "ADDR:PORT to listen on (default 127.0.0.1:7450)");
  serve
      ->add_option(
          "-l,--library", so->library,
          "Library: .fslib files, mesh files and directories of meshes, mixed (required, except with --nats)")
      ->expected(1, -1);
  serve->add_option("-o,--out", so->out_dir,
                    "Write result.json and an HTML report per scan into DIR/scan-<n>-id<scan id>/");
  serve->add_option("--params", so->params, "Match parameters: a preset or a JSON file");
  serve->add_option("--max-scans", so->max_scans, "Stop after N scans (0 = run until interrupted)");
  serve
      ->add_option(
          "--reconnect-grace", so->reconnect_grace_ms,
          "Milliseconds a scanner that disconnected mid-scan has to reconnect and resume it; after that "
          "the scan is recognized as PARTIAL")
      ->capture_default_str()
      ->check(CLI::Range(std::int64_t{0}, std::int64_t{3'600'000}));
  add_memory_budget_option(serve, so->memory_budget);
  add_segment_row_step_option(serve, so->segment_row_step);
  serve
      ->add_option("--max-clients", so->max_clients,
                   "Connections open at once (the scanner, a re-dial, probes); more are refused")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  serve->add_flag("--keep-scans", so->keep_scans,
                  "With -o: keep every scan as scan.fscan in its folder (failed scans always keep theirs)");
  serve->add_option("--test-pause-file", so->test_pause_file)->group("");  // tests: hold processing
  serve->add_flag("-q,--quiet", so->quiet, "Print nothing per scan");
  add_web_options(serve, so->web);
  add_gateway_options(serve, *so);
  serve->callback([so] { run_serve(*so); });

  auto o = std::make_shared<DemoOptions>();
  auto* demo =
      app.add_subcommand("demo",
                         "Hardware-in-the-loop demo: facetscan-fw-hil on simulated devices scans a scene and "
                         "streams it over TCP loopback; this process recognizes the objects");
  demo->add_option("--scene", o->scene,
                   "Shipped scene name (default, cube, pyramid, cube-pyramid-separate, "
                   "cube-occludes-pyramid, corner) or a scene JSON file");
  demo->add_option(
          "--galvo", o->galvo,
          "Galvo twin: gpio (the firmware's step/dir galvo on simulated GPIO lines; alias sim) or can "
          "(its CiA 402 master and a simulated drive on CAN; alias sim-can[:node=N,...])")
      ->capture_default_str();
  demo->add_option(
      "--fault", o->faults,
      "Inject a fault into the twins (repeatable): DEVICE.KIND[@TRIGGER][,count=N][,for=S], e.g. "
      "galvo.stall@step=120, camera.drop@frame=40,count=2, camera.timeout@t=1, laser.stuck@on=0");
  demo->add_option("-o,--out", o->out_dir, "Output directory (recording, result.json, HTML report)");
  demo->add_option("-l,--library", o->library, "Library (default: the scene's mesh folder)")->expected(1, -1);
  demo->add_option("--steps", o->steps, "Galvo steps of the scan (default: the scene's)");
  demo->add_option("--timeout", o->timeout_s, "Give up after this many seconds");
  demo->add_flag("-q,--quiet", o->quiet, "Less output");
  add_web_options(demo, o->web);
  demo->add_option("--http-wait", o->web.wait_s,
                   "With --http: wait up to S seconds for a page to open before the scan starts");
  demo->add_option("--fleet", o->fleet,
                   "The fleet demo: a local nats-server (shipped config), N simulated scanners each with its "
                   "gateway (serve --nats), --workers workers; prints each scanner's results as they arrive")
      ->check(CLI::Range(1, 16));
  demo->add_option("--workers", o->workers, "--fleet: workers (facetscan worker)")
      ->capture_default_str()
      ->check(CLI::Range(1, 16));
  demo->add_option("--fleet-scans", o->fleet_scans, "--fleet: scans per scanner")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  demo->callback([o] {
    if (o->fleet > 0) {
      FleetDemoOptions f;
      f.scanners = o->fleet;
      f.workers = o->workers;
      f.scans = o->fleet_scans;
      f.steps = o->steps;
      f.out_dir = o->out_dir;
      f.library = o->library;
      f.timeout_s = o->timeout_s;
      f.quiet = o->quiet;
      run_fleet_demo(f);
      return;
    }
    const int code = run_demo(*o);
    // With an injected fault the firmware is expected to stop in its fault state.
    if (code != 0 && o->faults.empty())
      throw Error(fmt::format("facetscan-fw-hil ended with exit code {}", code));
  });
}

}  // namespace fs::host::cli
