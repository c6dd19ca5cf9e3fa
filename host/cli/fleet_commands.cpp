// facetscan worker | results | submit | fleet-setup: fleets of scanners on NATS JetStream (docs/fleet.md).
// Everything here is opt-in with --nats URL; the broker-less commands (recognize, serve, demo) are unchanged.
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/crc32c.hpp"
#include "common/error.hpp"
#include "common/file_list.hpp"
#include "host/cli/commands.hpp"
#include "host/cli/fleet_submit.hpp"
#include "host/cli/memory_budget.hpp"
#include "host/cli/progress.hpp"
#include "host/fleet/ids.hpp"
#include "host/fleet/nats_connection.hpp"
#include "host/fleet/results_client.hpp"
#include "host/fleet/scan_publisher.hpp"
#include "host/fleet/streams.hpp"
#include "host/fleet/worker.hpp"
#include "host/io/scan_bytes.hpp"
#include "host/library/mesh_files.hpp"
#include "host/match/params.hpp"

namespace fs::host::cli {
namespace {

namespace stdfs = std::filesystem;

std::atomic<bool> g_stop{false};

extern "C" void on_stop_signal(int) { g_stop.store(true); }

void install_stop_signals() {
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

std::vector<std::uint8_t> read_bytes(const stdfs::path& p) {
  std::ifstream f(p, std::ios::binary);
  if (!f) throw Error(p.string() + ": cannot open");
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

// ---- worker

struct WorkerCli {
  fleet::NatsOptions nats;
  std::vector<std::string> library;
  std::string params = "t9.3";
  std::string memory_budget;
  std::string worker_id;
  int threads = 1;
  int max_streams = fleet::WorkerOptions{}.max_streams;
  double part_timeout_s = 60.0;
  int test_hold_ms = 0;
  fleet::FleetSettings settings;
};

void run_worker(WorkerCli& o) {
  install_stop_signals();
  if (!o.worker_id.empty()) fleet::check_scanner_id(o.worker_id, "worker id");
  fleet::check_transport_policy(o.nats.url, o.nats.insecure);  // before the library is loaded
  const Library library = load_or_build_library(o.library);
  if (library.models.empty()) throw Error("the library has no models");
  fleet::WorkerOptions wo;
  wo.worker_id = o.worker_id;
  wo.threads = o.threads;
  wo.max_streams = o.max_streams;
  wo.part_timeout_ms = static_cast<std::int64_t>(o.part_timeout_s * 1000);
  wo.test_hold_ms = o.test_hold_ms;
  wo.settings = o.settings;
  wo.limits = memory_budget_limits(o.memory_budget);
  wo.params.match = match::read_params(o.params);
  // Scans run side by side on `threads` threads; each recognition then matches on one core.
  wo.params.threads = o.threads > 1 ? 1 : 0;
  for (const auto& l : o.library)
    wo.library_id += (wo.library_id.empty() ? "" : ",") + stdfs::path(l).filename().string();
  // The hash names the library as used (built from meshes or read from a .fslib): CRC-32C of its .fslib
  // image.
  const stdfs::path tmp = stdfs::temp_directory_path() / fmt::format("facetscan-worker-{}.fslib", ::getpid());
  library.save(tmp);
  wo.library_hash = fmt::format("{:08x}", crc32c(read_bytes(tmp)));
  stdfs::remove(tmp);
  wo.log = [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); };
  o.nats.name = "facetscan-worker";
  fleet::NatsConnection connection(o.nats);
  fleet::Worker worker(connection, library, wo);
  worker.run(g_stop);
}

// ---- results

struct ResultsCli {
  fleet::NatsOptions nats;
  std::string scanner;
  bool follow = false;
  bool dead = false;
  bool json = false;
};

void run_results(ResultsCli& o) {
  install_stop_signals();
  o.nats.name = "facetscan-results";
  fleet::NatsConnection connection(o.nats);
  fleet::ResultsReader reader(
      connection, o.dead ? fleet::ResultsReader::Source::Dead : fleet::ResultsReader::Source::Results,
      o.scanner);
  while (!g_stop.load()) {
    // Without --follow: what is stored now, then exit (a filter matching nothing ends after one quiet
    // second).
    const auto r = reader.next(o.follow ? 500 : 1000);
    if (!r) {
      if (!o.follow) break;
      continue;
    }
    if (o.json) {
      if (o.dead) {
        const nlohmann::json j = {{"scan_id", r->scan_id},
                                  {"scanner_id", r->scanner_id},
                                  {"reason", r->reason},
                                  {"bytes", r->body.size()},
                                  {"sequence", r->sequence}};
        std::printf("%s\n", j.dump().c_str());
      } else {
        std::printf("%s\n", r->body.c_str());
      }
    } else {
      std::printf("%s\n", fleet::result_summary_line(*r, o.dead).c_str());
    }
    std::fflush(stdout);
    if (!o.follow && r->pending == 0) break;
  }
}

// ---- submit

}  // namespace

void run_submit(SubmitCli& o) {
  install_stop_signals();
  fleet::check_scanner_id(o.scanner);
  const auto files = collect_files(
      o.inputs, [](const stdfs::path& p) { return p.extension() == ".fscan"; }, ".fscan files");
  o.nats.name = "facetscan-submit";
  fleet::NatsConnection connection(o.nats);
  // Made before publishing so that no result is missed; it reads the stored results from the start.
  std::unique_ptr<fleet::ResultsReader> results, dead;
  if (o.wait) {
    results =
        std::make_unique<fleet::ResultsReader>(connection, fleet::ResultsReader::Source::Results, o.scanner);
    dead = std::make_unique<fleet::ResultsReader>(connection, fleet::ResultsReader::Source::Dead, o.scanner);
  }
  fleet::ScanPublisher publisher(connection, o.scanner);
  std::map<std::string, std::string> waiting;  // scan id -> file
  for (const auto& f : files) {
    const auto bytes = read_bytes(f);
    const fleet::PublishedScan p = publisher.publish(bytes);
    if (!o.quiet)
      std::printf("submitted %s as %s (%zu bytes, %.1f ms, SCANS seq %llu%s)\n", f.string().c_str(),
                  p.message_id.c_str(), p.bytes, p.ms, static_cast<unsigned long long>(p.sequence),
                  p.duplicate ? ", duplicate: already stored" : "");
    waiting[p.message_id] = f.string();
  }
  std::fflush(stdout);
  if (!o.wait) return;
  const std::size_t total = waiting.size();
  Progress progress(total, o.quiet);
  std::set<std::string> seen;
  int failed = 0;
  const auto start = std::chrono::steady_clock::now();
  while (!waiting.empty() && !g_stop.load()) {
    if (o.timeout_s > 0 &&
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() > o.timeout_s)
      throw Error(fmt::format("--timeout: {} of {} result(s) still missing", waiting.size(), total));
    bool got = false;
    for (auto* reader : {results.get(), dead.get()}) {
      const auto r = reader->next(reader == results.get() ? 200 : 1);
      if (!r) continue;
      got = true;
      const auto it = waiting.find(r->scan_id);
      if (it == waiting.end()) continue;  // an older result of this scanner
      const bool is_dead = reader == dead.get();
      failed += is_dead ? 1 : 0;
      std::printf("%s: %s\n", it->second.c_str(), fleet::result_summary_line(*r, is_dead).c_str());
      std::fflush(stdout);
      waiting.erase(it);
      progress.update(total - waiting.size(), r->scan_id);
    }
    (void)got;
  }
  progress.finish();
  if (!waiting.empty())
    throw Error(fmt::format("interrupted: {} of {} result(s) missing", waiting.size(), total));
  if (failed > 0) throw Error(fmt::format("{} of {} scan(s) failed (dead-lettered)", failed, total));
}

namespace {

// ---- fleet-setup

struct SetupCli {
  fleet::NatsOptions nats;
  fleet::FleetSettings settings;
  double ack_wait_s = 30;
};

void run_setup(SetupCli& o) {
  o.settings.ack_wait_ms = static_cast<std::int64_t>(o.ack_wait_s * 1000);
  o.nats.name = "facetscan-fleet-setup";
  fleet::NatsConnection connection(o.nats);
  const fleet::ConsumerSettings c = fleet::ensure_fleet(connection.js(), o.settings, true);
  std::printf(
      "streams %s, %s, %s and consumer %s.%s ready (AckWait %lld ms, MaxDeliver %d, replicas %d); "
      "server max_payload %lld bytes\n",
      fleet::kScansStream, fleet::kResultsStream, fleet::kDeadStream, fleet::kScansStream,
      fleet::kWorkersConsumer, static_cast<long long>(c.ack_wait_ms), c.max_deliver, o.settings.replicas,
      static_cast<long long>(connection.max_payload()));
}

void add_settings_options(CLI::App* cmd, fleet::FleetSettings& s, double* ack_wait_s) {
  cmd->add_option("--replicas", s.replicas, "Stream replicas (3 on a 3-node cluster)")
      ->check(CLI::Range(1, 5));
  cmd->add_option("--max-deliver", s.max_deliver, "Deliveries of a scan before it goes to DEAD")
      ->check(CLI::Range(1, 100));
  cmd->add_option("--max-ack-pending", s.max_ack_pending, "Scans in flight over all workers")
      ->check(CLI::PositiveNumber);
  if (ack_wait_s != nullptr)
    cmd->add_option("--ack-wait", *ack_wait_s, "Seconds without ack or progress before a scan is redelivered")
        ->check(CLI::Range(0.5, 3600.0));
}

}  // namespace

void add_nats_options(CLI::App* cmd, fleet::NatsOptions& o, bool required) {
  cmd->add_option("--nats", o.url,
                  "NATS server URL(s): nats://HOST:4222 (loopback), tls://HOST:4222, comma-separated for a "
                  "cluster; user and password from $FACETSCAN_NATS_USER / $FACETSCAN_NATS_PASSWORD")
      ->required(required);
  cmd->add_flag("--insecure", o.insecure, "Allow plain-text nats:// to a non-loopback server");
  cmd->add_option("--nats-ca", o.ca_file, "TLS: CA certificate that signed the server's certificate");
  cmd->add_option("--nats-cert", o.cert_file, "TLS: client certificate (mutual TLS)");
  cmd->add_option("--nats-key", o.key_file, "TLS: client key (mutual TLS)");
}

void add_fleet_commands(CLI::App& app) {
  auto w = std::make_shared<WorkerCli>();
  auto wack = std::make_shared<double>(30.0);
  auto* worker = app.add_subcommand(
      "worker", "Fleet worker: recognize the scans of the NATS stream SCANS, publish the results to RESULTS");
  add_nats_options(worker, w->nats);
  worker
      ->add_option("-l,--library", w->library,
                   "Library: .fslib files, mesh files and directories of meshes, mixed (repeatable)")
      ->required()
      ->expected(1, -1);
  worker->add_option("--threads", w->threads, "Scans recognized at once")->check(CLI::Range(1, 256));
  worker
      ->add_option("--max-streams", w->max_streams,
                   "Streamed scans (serve --nats --stream) read at once besides those recognized")
      ->capture_default_str()
      ->check(CLI::Range(1, 1024));
  worker
      ->add_option("--part-timeout", w->part_timeout_s,
                   "Seconds without a new part after which a streamed scan fails (its gateway stopped)")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 86400.0));
  worker->add_option("--worker-id", w->worker_id, "Name in the results (default: HOSTNAME-PID)");
  worker->add_option("--params", w->params, "Match parameters: a preset or a JSON file");
  add_memory_budget_option(worker, w->memory_budget);
  add_settings_options(worker, w->settings, wack.get());
  worker->add_option("--test-hold-ms", w->test_hold_ms)
      ->group("");  // tests: hold each scan before recognizing
  worker->callback([w, wack] {
    w->settings.ack_wait_ms = static_cast<std::int64_t>(*wack * 1000);
    run_worker(*w);
  });

  auto r = std::make_shared<ResultsCli>();
  auto* results = app.add_subcommand("results", "Print the fleet's results (stream RESULTS) or dead letters");
  add_nats_options(results, r->nats);
  results->add_option("--scanner", r->scanner, "Only this scanner's results");
  results->add_flag("-f,--follow", r->follow, "Keep printing new results as they arrive");
  results->add_flag("--dead", r->dead, "Print the dead letters (stream DEAD) instead, with their reasons");
  results->add_flag("--json", r->json, "One JSON document per line (the result as published)");
  results->callback([r] { run_results(*r); });

  auto s = std::make_shared<SubmitCli>();
  auto* submit = app.add_subcommand(
      "submit",
      "Publish .fscan files to the fleet (stream SCANS) as a gateway does; --wait for their results");
  add_nats_options(submit, s->nats);
  submit->add_option("inputs", s->inputs, ".fscan files or directories")->required();
  submit->add_option("--scanner", s->scanner, "Scanner id of the scans (subject facetscan.scans.ID)");
  submit->add_flag("--wait", s->wait, "Wait for every scan's result (or dead letter) and print it");
  submit->add_option("--timeout", s->timeout_s, "--wait: give up after this many seconds (0 = never)");
  submit->add_flag("-q,--quiet", s->quiet, "No line per file, no progress bar");
  submit->callback([s] { run_submit(*s); });

  auto u = std::make_shared<SetupCli>();
  auto* setup =
      app.add_subcommand("fleet-setup",
                         "Create (or check) the fleet's streams SCANS, RESULTS, DEAD and the workers' "
                         "consumer (run once, as the admin user)");
  add_nats_options(setup, u->nats);
  add_settings_options(setup, u->settings, &u->ack_wait_s);
  setup->callback([u] { run_setup(*u); });
}

}  // namespace fs::host::cli
