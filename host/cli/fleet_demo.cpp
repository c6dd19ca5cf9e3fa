#include "host/cli/fleet_demo.hpp"

#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>

#include <fmt/format.h>

#include "common/error.hpp"
#include "host/cli/child_process.hpp"
#include "host/cli/install_paths.hpp"
#include "host/cli/local_fleet.hpp"
#include "host/fleet/results_client.hpp"

namespace fs::host::cli {
namespace stdfs = std::filesystem;
using Clock = std::chrono::steady_clock;

int run_fleet_demo(const FleetDemoOptions& o) {
  if (o.scanners < 1 || o.workers < 1) throw Error("--fleet and --workers must be at least 1");
  const stdfs::path scenes = scenes_dir();
  const stdfs::path bin = self_dir();
  const stdfs::path fw = bin / "facetscan-fw-hil";
  if (!stdfs::exists(fw)) throw Error(fw.string() + ": facetscan-fw-hil not found next to facetscan");

  LocalFleet fleet(stdfs::path(o.out_dir) / "fleet", bin);
  const auto start = Clock::now();
  if (!o.quiet) {
    fmt::print(
        "facetscan demo --fleet {}: nats-server (JetStream, TLS) at {}, {} worker(s), {} scanner(s) each "
        "with its gateway; logs in {}\n",
        o.scanners, fleet.url(), o.workers, o.scanners, fleet.logs().string());
    std::fflush(stdout);
  }
  std::vector<std::string> library = o.library;
  if (library.empty()) library.push_back((scenes / "meshes").string());
  for (int w = 1; w <= o.workers; ++w) fleet.start_worker(fmt::format("worker-{}", w), library);
  std::vector<int> ports;
  for (int i = 1; i <= o.scanners; ++i) {
    ports.push_back(free_local_port());
    fleet.start_gateway(fmt::format("scanner-{}", i), ports.back());
  }
  // The results, read as the shop floor does; closed before the fleet stops.
  auto connection = std::make_unique<fleet::NatsConnection>(fleet.user("shopfloor"));
  auto results = std::make_unique<fleet::ResultsReader>(*connection, fleet::ResultsReader::Source::Results);

  // The scanners: facetscan-fw-hil on the twins, one shipped scene each, its scans one after the other.
  const std::vector<std::string> scene_names = {
      "default", "cube-pyramid-separate", "corner", "cube-occludes-pyramid", "cube", "pyramid"};
  std::vector<std::unique_ptr<ChildProcess>> scanners;
  for (int i = 1; i <= o.scanners; ++i) {
    const std::string& scene = scene_names[static_cast<std::size_t>(i - 1) % scene_names.size()];
    std::string cmd;
    for (int k = 0; k < o.scans; ++k)
      cmd += fmt::format("'{}' --scene '{}' --stream 127.0.0.1:{} --scan-id {}{} || exit $?; ", fw.string(),
                         (scenes / (scene + ".json")).string(), ports[static_cast<std::size_t>(i - 1)], k + 1,
                         o.steps > 0 ? fmt::format(" --steps {}", o.steps) : "");
    if (!o.quiet)
      fmt::print("scanner-{}: scene {}, {} scan(s) to its gateway 127.0.0.1:{}\n", i, scene, o.scans,
                 ports[static_cast<std::size_t>(i - 1)]);
    scanners.push_back(std::make_unique<ChildProcess>(std::vector<std::string>{"/bin/sh", "-c", cmd},
                                                      std::map<std::string, std::string>{},
                                                      fleet.logs() / fmt::format("scanner-{}.log", i)));
  }
  std::fflush(stdout);

  const int expected = o.scanners * o.scans;
  int received = 0;
  const auto deadline = start + std::chrono::seconds(o.timeout_s);
  std::string problem;
  while (received < expected && problem.empty()) {
    if (const auto r = results->next(250)) {
      ++received;
      fmt::print("{}\n", fleet::result_summary_line(*r));
      std::fflush(stdout);
      continue;
    }
    for (auto& s : scanners)
      if (problem.empty() && !s->running() && s->wait(0) != 0)
        problem = fmt::format("a scanner failed ({}):\n{}", s->log().string(), s->log_tail());
    if (problem.empty()) problem = fleet.exited_process();
    if (problem.empty() && Clock::now() > deadline)
      problem = fmt::format("--timeout {} s: {} of {} result(s) arrived", o.timeout_s, received, expected);
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  results.reset();
  connection.reset();
  for (auto& s : scanners) s->stop(SIGTERM, 5000);
  fleet.stop();
  if (!problem.empty()) throw Error("demo --fleet: " + problem);
  if (!o.quiet)
    fmt::print("fleet demo: {} of {} scan(s) recognized by {} worker(s) in {:.1f} s; logs in {}\n", received,
               expected, o.workers, seconds, fleet.logs().string());
  return 0;
}

}  // namespace fs::host::cli
