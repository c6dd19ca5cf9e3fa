// Fleet benchmark (docs/fleet.md#benchmark): a local fleet (host/cli/local_fleet.hpp: nats-server from the
// shipped config, TLS, file storage) with 1, 2 and 4 workers (`facetscan worker`), fed by K simulated
// scanners that publish 500-stripe (--steps) .fscan scans (recorded with facetscan-fw-hil) as the gateway
// does, each at scanner rate (one scan per --period seconds).
//
//   bench_fleet [--workers 1,2,4] [--scanners 3] [--period 2.5] [--latency-scans 12] [--burst 16]
//               [--steps 500] [--stream] [--dir DIR]
//
// --stream: the latency phase streams each scan as `serve --nats --stream` does
// (host/fleet/scan_streamer.hpp): its stripes go out as parts at the scanner's rate (200 stripes/s) and
// ScanEnd is the end of the last stripe; the burst phase publishes whole scans as without it.
//
// Per worker count:
//   latency   scans published at scanner rate (no queueing expected): ScanEnd (publish starts) -> result
//             received, p50 / p99; the broker path = that latency minus the worker's own load + recognition
//             time of the scan (the result's timings), p50 / p99
//   burst     --burst scans stored first, then the workers start: scans/s between the first and the last
//             result (the workers' throughput, pulling from the stream)
// Before that: local recognition of the same scans in this process (load + triangulate + recognize), and the
// gateway's spool write (fsync) per scan. Every run checks that each scan got exactly one result.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/error.hpp"
#include "host/cli/child_process.hpp"
#include "host/cli/local_fleet.hpp"
#include "host/fleet/ids.hpp"
#include "host/fleet/results_client.hpp"
#include "host/fleet/scan_publisher.hpp"
#include "host/fleet/scan_spool.hpp"
#include "host/fleet/scan_streamer.hpp"
#include "host/io/scan_bytes.hpp"
#include "host/library/mesh_files.hpp"
#include "host/match/params.hpp"
#include "host/recognize/recognizer.hpp"
#include "support/quantile.hpp"

namespace {

namespace stdfs = std::filesystem;
using Clock = std::chrono::steady_clock;
using namespace fs::host;

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

using fs::test::quantile;

std::vector<std::uint8_t> read_bytes(const stdfs::path& p) {
  std::ifstream f(p, std::ios::binary);
  if (!f) throw fs::Error(p.string() + ": cannot open");
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

// One round: per scan the latency (ms), the worker's load + recognize time and their difference (the broker
// path).
struct Round {
  std::vector<double> latency, worker_ms, broker;
  std::vector<double> publish_ms, queued_ms, extra_ms,
      after_ms;  // broker path parts: publish, stored -> worker, result -> reader
  double seconds = 0;
  int results = 0, duplicates = 0;
};

// Streams one recorded scan as the streaming gateway does, at the scanner's rate (200 stripes/s): ScanBegin,
// the stripes paced, then the end. `sent[id]` is the end (the scanner's ScanEnd), `publish_ms[id]` the end
// until the last part was stored.
void stream_scan(fleet::ScanStreamer& streamer, const std::vector<std::uint8_t>& image,
                 const std::string& scanner, std::mutex& mu, std::map<std::string, Clock::time_point>& sent,
                 std::map<std::string, double>& publish_ms) {
  Scan scan;
  load_scan_bytes(image, "scan", scan);
  const auto t0 = Clock::now();
  streamer.begin(scanner, scan.begin_message());
  std::uint32_t n = 0;
  for (std::uint32_t k = 0; k < scan.slot_count(); ++k) {
    if (!scan.has_stripe(k)) continue;
    std::this_thread::sleep_until(t0 + std::chrono::microseconds(5000) * ++n);  // 200 stripes/s
    const auto points = scan.stripe_points(k);
    fs::msg::Stripe m;
    m.header = scan.stripe_header(k);
    m.points =
        std::span<fs::msg::StripePoint>(const_cast<fs::msg::StripePoint*>(points.data()), points.size());
    streamer.stripe(m);
  }
  const std::string id = streamer.open_scan_id();
  {
    std::lock_guard lock(mu);
    sent[id] = Clock::now();
  }
  const fleet::StreamOutcome o = streamer.wait(streamer.end(scan));
  if (!o.stored) throw fs::Error("stream of " + id + " failed: " + o.error);
  std::lock_guard lock(mu);
  publish_ms[id] = o.last_ms;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_fleet: throughput and latency of the NATS fleet (docs/fleet.md#benchmark)"};
  std::vector<int> worker_counts = {1, 2, 4};
  int scanners = 3, latency_scans = 12, burst = 16;
  double period_s = 2.5;
  std::string dir = "bench-fleet";
  bool plain = false;
  bool stream = false;
  int steps = 500;
  app.add_option("--workers", worker_counts, "Worker counts to run")->delimiter(',');
  app.add_option("--scanners", scanners, "Simulated scanners (distinct scan streams)")
      ->check(CLI::Range(1, 32));
  app.add_option("--period", period_s, "Seconds between two scans of one scanner (scanner rate)");
  app.add_option("--latency-scans", latency_scans, "Scans of the latency phase per worker count");
  app.add_option("--burst", burst, "Scans published at once in the throughput phase");
  app.add_option("--dir", dir, "Working folder (fleet, store, logs, recorded scans)");
  app.add_option("--steps", steps, "Stripes per scan (the scan's size: ~12 kB per stripe)")
      ->check(CLI::Range(10, 4000));
  app.add_flag("--stream", stream,
               "Latency phase: stream each scan in parts while it is scanned (serve --stream)");
  app.add_flag("--plain", plain, "Plain nats:// on loopback instead of the shipped TLS (what TLS costs)");
  CLI11_PARSE(app, argc, argv);
  try {
    const stdfs::path bin = stdfs::read_symlink("/proc/self/exe").parent_path();
    const stdfs::path source = FACETSCAN_SOURCE_DIR;
    const stdfs::path work = stdfs::absolute(dir);
    stdfs::create_directories(work / "scans");
    // Distinct 500-stripe scans: the shipped scenes, each scanner its own scan ids.
    const std::vector<std::string> scenes = {"default", "cube-pyramid-separate", "corner"};
    const int total_scans = std::max(latency_scans, burst);
    std::vector<std::pair<std::string, std::vector<std::uint8_t>>> scans;  // scene, image
    for (int i = 0; i < total_scans; ++i) {
      const std::string& scene = scenes[static_cast<std::size_t>(i) % scenes.size()];
      const stdfs::path f = work / "scans" / fmt::format("{}-{}-{}.fscan", scene, steps, i + 1);
      if (!stdfs::exists(f)) {
        fs::host::cli::ChildProcess fw(
            {(bin / "facetscan-fw-hil").string(), "--scene",
             (source / "hw-sim" / "scenes" / (scene + ".json")).string(), "--record", f.string(), "--scan-id",
             std::to_string(i + 1), "--steps", std::to_string(steps)},
            {}, work / "scans" / "record.log");
        if (fw.wait(120000) != 0) throw fs::Error("facetscan-fw-hil --record failed:\n" + fw.log_tail());
      }
      scans.emplace_back(scene, read_bytes(f));
    }
    const double mb = static_cast<double>(scans[0].second.size()) / 1e6;
    fmt::print(
        "bench_fleet: {} scans ({:.1f} MB each, {} stripes), {} simulated scanner(s) at one scan per {} s\n",
        scans.size(), mb, steps, scanners, period_s);

    // Local recognition of the same scans (what a worker does, in this process, one thread).
    const Library library = load_or_build_library({(source / "hw-sim" / "scenes" / "meshes").string()});
    rec::RecognizeParams params;
    params.match = match::read_params("t9.3");
    std::vector<double> local_ms;
    {
      OrganizedCloud cloud;
      std::unique_ptr<rec::Recognizer> recognizer;
      for (int pass = 0; pass < 2; ++pass)  // the first pass warms up
        for (const auto& [scene, image] : scans) {
          const auto t0 = Clock::now();
          load_cloud_bytes(image, scene, cloud);
          if (!recognizer)
            recognizer = std::make_unique<rec::Recognizer>(library, params, cloud.points.size());
          recognizer->recognize(cloud);
          if (pass == 1) local_ms.push_back(ms_since(t0));
        }
    }
    // The gateway's spool write per scan (written, fsync'd, removed).
    std::vector<double> spool_ms;
    {
      fleet::ScanSpool spool(work / "spool-bench", std::uint64_t(1) << 33);
      for (const auto& [scene, image] : scans) {
        const auto t0 = Clock::now();
        const auto e = spool.put(image, "bench", ScanStatus::Complete);
        spool_ms.push_back(ms_since(t0));
        spool.remove(e);
      }
    }
    fmt::print("local recognition (load + triangulate + recognize, 1 thread): p50 {:.1f} ms, p90 {:.1f} ms\n",
               quantile(local_ms, 0.5), quantile(local_ms, 0.9));
    fmt::print("gateway spool write (fsync): p50 {:.1f} ms, p99 {:.1f} ms\n\n", quantile(spool_ms, 0.5),
               quantile(spool_ms, 0.99));
    fmt::print(
        "| workers | latency p50 / p99 (ms) | broker path p50 / p99 (ms) | worker load+recognize p50 (ms) | "
        "burst of {}: scans/s | lost | duplicates |\n| --- | --- | --- | --- | --- | --- | --- |\n",
        burst);
    std::fflush(stdout);

    std::map<int, double> rate;
    bool all_ok = true;
    const std::string meshes = (source / "hw-sim" / "scenes" / "meshes").string();
    // A fresh fleet (new store: the scans are new to it) with `workers` workers that are pulling.
    const auto start_workers = [&](fs::host::cli::LocalFleet& fleet, int workers) {
      for (int w = 1; w <= workers; ++w) fleet.start_worker(fmt::format("w{}", w), {meshes});
    };
    const auto start_fleet = [&](const std::string& name, int workers) {
      auto fleet = std::make_unique<fs::host::cli::LocalFleet>(work / name, bin,
                                                               fs::host::fleet::FleetSettings{}, !plain);
      start_workers(*fleet, workers);
      for (int w = 1; w <= workers; ++w) {
        const stdfs::path log = fleet->logs() / fmt::format("w{}.log", w);
        const auto until = Clock::now() + std::chrono::seconds(60);
        for (;;) {
          std::ifstream f(log);
          const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
          if (text.find("ready (") != std::string::npos) break;
          if (Clock::now() > until) throw fs::Error(log.string() + ": worker not ready:\n" + text);
          std::this_thread::sleep_for(std::chrono::milliseconds(50));
        }
      }
      return fleet;
    };
    // Publishes scans[0 .. count) from `scanners` threads (paced: one scan per period per scanner, staggered;
    // else all at once) and reads the results until every scan has one. late_workers > 0: the scans are all
    // stored first, then that many workers start (the throughput of the workers alone).
    const auto run_round = [&](fs::host::cli::LocalFleet& fleet, int count, bool paced, int late_workers) {
      fleet::NatsConnection pub(fleet.user("gateway"));
      fleet::NatsConnection sub(fleet.user("shopfloor"));
      fleet::ResultsReader reader(sub, fleet::ResultsReader::Source::Results);
      std::mutex mu;
      std::map<std::string, Clock::time_point> sent;
      std::map<std::string, double> publish_ms;
      Round r;
      std::vector<std::thread> threads;
      const auto start = Clock::now();
      for (int s = 0; s < scanners; ++s)
        threads.emplace_back([&, s] {
          fleet::ScanPublisher publisher(pub, fmt::format("scanner-{}", s + 1));
          fleet::ScanStreamer streamer(pub, fleet::FleetSettings{});
          int k = 0;
          for (int i = s; i < count; i += scanners, ++k) {
            if (paced)
              std::this_thread::sleep_until(
                  start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(
                              period_s * (k + static_cast<double>(s) / scanners))));
            const auto& image = scans[static_cast<std::size_t>(i)].second;
            if (stream && paced) {
              stream_scan(streamer, image, publisher.scanner_id(), mu, sent, publish_ms);
              continue;
            }
            const fs::msg::ScanBegin b = peek_scan_begin(image, "scan");
            const std::string id =
                fleet::scan_message_id(publisher.scanner_id(), b.scan_id, b.start_time_ns, image);
            {
              std::lock_guard lock(mu);
              sent[id] = Clock::now();  // the scan's ScanEnd reached the gateway: publishing starts
            }
            const double ms = publisher.publish(image).ms;
            std::lock_guard lock(mu);
            publish_ms[id] = ms;
          }
        });
      if (late_workers > 0) {
        for (auto& t : threads) t.join();
        threads.clear();
        start_workers(fleet, late_workers);
      }
      std::map<std::string, int> seen;
      Clock::time_point first{}, last{};
      const auto deadline = Clock::now() + std::chrono::seconds(300 + static_cast<int>(period_s * count));
      while (static_cast<int>(seen.size()) < count && Clock::now() < deadline) {
        const auto res = reader.next(500);
        if (!res) continue;
        const auto arrived = Clock::now();
        if (seen.empty()) first = arrived;
        last = arrived;
        if (++seen[res->scan_id] > 1) {
          ++r.duplicates;
          continue;
        }
        std::lock_guard lock(mu);
        const auto it = sent.find(res->scan_id);
        if (it == sent.end()) continue;
        const double latency = std::chrono::duration<double, std::milli>(arrived - it->second).count();
        const nlohmann::json j = nlohmann::json::parse(res->body);
        const double worker =
            j["timings"]["load_ms"].get<double>() + j["timings"]["recognize_ms"].get<double>();
        r.latency.push_back(latency);
        r.worker_ms.push_back(worker);
        r.broker.push_back(latency - worker);
        const auto& t = j["timings"];
        const double pub_ms = publish_ms.count(res->scan_id) ? publish_ms[res->scan_id] : 0.0;
        r.publish_ms.push_back(pub_ms);
        // A streamed scan was taken at its ScanBegin: what follows its end is the last part's way to the
        // worker.
        const double queued =
            t.contains("last_part_ms") ? t["last_part_ms"].get<double>() : t["queued_ms"].get<double>();
        r.queued_ms.push_back(queued);
        r.extra_ms.push_back(t["worker_ms"].get<double>() - worker);
        r.after_ms.push_back(latency - pub_ms - queued - t["worker_ms"].get<double>());
      }
      r.seconds = std::chrono::duration<double>(last - first).count();  // first to last result
      for (auto& t : threads) t.join();
      std::this_thread::sleep_for(std::chrono::milliseconds(500));  // a duplicate would come now
      while (const auto res = reader.next(100))
        if (++seen[res->scan_id] > 1) ++r.duplicates;
      r.results = static_cast<int>(seen.size());
      return r;
    };
    for (int workers : worker_counts) {
      Round lat, thr;
      {
        auto fleet = start_fleet(fmt::format("fleet-{}-latency", workers), workers);
        lat = run_round(*fleet, latency_scans, true, 0);
      }
      {
        auto fleet = start_fleet(fmt::format("fleet-{}-burst", workers), 0);
        thr = run_round(*fleet, burst, false, workers);
      }
      rate[workers] = thr.results > 1 && thr.seconds > 0 ? (thr.results - 1) / thr.seconds : 0.0;
      const int lost = (latency_scans - lat.results) + (burst - thr.results);
      all_ok = all_ok && lost == 0 && lat.duplicates + thr.duplicates == 0;
      fmt::print("| {} | {:.0f} / {:.0f} | {:.1f} / {:.1f} | {:.0f} | {:.2f} | {} | {} |\n", workers,
                 quantile(lat.latency, 0.5), quantile(lat.latency, 0.99), quantile(lat.broker, 0.5),
                 quantile(lat.broker, 0.99), quantile(lat.worker_ms, 0.5), rate[workers], lost,
                 lat.duplicates + thr.duplicates);
      fmt::print(
          "|   | broker path parts p50: publish + store {:.1f}, stored -> worker {:.1f}, worker outside "
          "load+recognize {:.1f}, result publish -> reader {:.1f} ms{} | | | | | |\n",
          quantile(lat.publish_ms, 0.5), quantile(lat.queued_ms, 0.5), quantile(lat.extra_ms, 0.5),
          quantile(lat.after_ms, 0.5), stream ? " (streamed: the last part)" : "");
      std::fflush(stdout);
    }
    if (rate.count(1) && rate.count(2))
      fmt::print("\nthroughput 2 workers / 1 worker: {:.2f}x ({} cores online)\n", rate[2] / rate[1],
                 std::thread::hardware_concurrency());
    if (!all_ok) {
      fmt::print("bench_fleet: FAILED: scans lost or recognized twice\n");
      return 1;
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_fleet: error: %s\n", e.what());
    return 1;
  }
}
