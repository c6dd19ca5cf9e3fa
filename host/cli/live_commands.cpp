#include "host/cli/live_commands.hpp"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include "common/error.hpp"
#include "host/cli/progress.hpp"
#include "host/io/scan.hpp"
#include "host/io/stream_server.hpp"
#include "host/io/triangulate.hpp"
#include "host/library/mesh_files.hpp"
#include "host/match/params.hpp"
#include "host/recognize/recognizer.hpp"
#include "host/recognize/report.hpp"

extern char** environ;

namespace fs::host::cli {
namespace {

namespace stdfs = std::filesystem;

// Recognizes scans as they are delivered: triangulation -> recognition -> table, JSON and report.
class ScanHandler {
 public:
  ScanHandler(const Library& library, rec::RecognizeParams params, std::string out_dir, bool quiet)
      : library_(library), params_(std::move(params)), out_dir_(std::move(out_dir)), quiet_(quiet) {}

  // Called before a scan's result is printed (the demo ends its progress bar there).
  void set_before_result(std::function<void(const Scan&)> f) { before_result_ = std::move(f); }

  void operator()(const Scan& scan) {
    ++scans_;
    if (before_result_) before_result_(scan);
    const bool partial = !scan.complete();
    triangulator_.triangulate(scan, cloud_);
    if (!recognizer_ || recognizer_cells_ < cloud_.points.size()) {
      recognizer_ = std::make_unique<rec::Recognizer>(library_, params_, cloud_.points.size());
      recognizer_cells_ = cloud_.points.size();
    }
    const Plane table = scan.begin_message().calibration.table;
    const rec::Recognition& r = recognizer_->recognize(cloud_, &table);
    last_objects_ = static_cast<int>(r.objects.size());
    if (!quiet_) {
      fmt::print("\nscan {} ({} of {} stripes{}): {} object(s)\n", scan.scan_id(), scan.stripes_received(),
                 scan.slot_count(), partial ? fmt::format(", PARTIAL: {}", to_string(scan.status())) : "",
                 r.objects.size());
      fmt::print("{}", rec::result_table(r, library_));
      fmt::print("recognition: {:.0f} ms (segmentation {:.0f}, matching {:.0f}, verification {:.0f})\n",
                 r.stats.total_ms, r.stats.segment_ms, r.stats.match_ms, r.stats.verify_ms);
    }
    if (!out_dir_.empty()) {
      const stdfs::path dir = stdfs::path(out_dir_) / fmt::format("scan-{:03}-id{}", scans_, scan.scan_id());
      rec::write_report(dir / "report", fmt::format("scan {}", scan.scan_id()), cloud_, *recognizer_, r);
      nlohmann::json j = rec::to_json(r, library_);
      j["scan"] = {{"scan_id", scan.scan_id()},
                   {"status", to_string(scan.status())},
                   {"partial", partial},
                   {"stripes", scan.stripes_received()},
                   {"steps", scan.slot_count()}};
      std::ofstream(dir / "result.json") << j.dump(2) << "\n";
      last_dir_ = dir;
      if (!quiet_) fmt::print("report: {}\n", (dir / "report" / "index.html").string());
    }
    std::fflush(stdout);  // a log file or pipe sees each scan's result as it is recognized
  }
  int scans() const { return scans_; }
  int last_objects() const { return last_objects_; }
  const stdfs::path& last_dir() const { return last_dir_; }

 private:
  const Library& library_;
  rec::RecognizeParams params_;
  std::string out_dir_;
  bool quiet_;
  Triangulator triangulator_;
  OrganizedCloud cloud_;
  std::unique_ptr<rec::Recognizer> recognizer_;
  std::size_t recognizer_cells_ = 0;
  std::function<void(const Scan&)> before_result_;
  int scans_ = 0;
  int last_objects_ = -1;
  stdfs::path last_dir_;
};

std::atomic<StreamServer*> g_server{nullptr};
extern "C" void on_signal(int) {
  if (StreamServer* s = g_server.load()) s->stop();
}

struct ServeOptions {
  std::string listen = "127.0.0.1:7450";
  std::vector<std::string> library;
  std::string out_dir;
  std::string params = "t9.3";
  int max_scans = 0;
  std::int64_t reconnect_grace_ms = StreamServerOptions{}.reconnect_grace_ms;
  bool quiet = false;
};

void run_serve(const ServeOptions& o) {
  const Library library = load_or_build_library(o.library);
  rec::RecognizeParams params;
  params.match = match::read_params(o.params);
  ScanHandler handler(library, params, o.out_dir, o.quiet);
  StreamServerOptions so;
  so.listen = o.listen;
  so.reconnect_grace_ms = o.reconnect_grace_ms;
  StreamServer server(so, [&](const Scan& s) { handler(s); });
  server.start();
  g_server = &server;
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  if (!o.quiet)
    fmt::print("facetscan serve: listening on {} (port {}), {} models; Ctrl-C stops\n", o.listen,
               server.port(), library.models.size());
  std::fflush(stdout);
  while (server.poll_once(200)) {
    if (o.max_scans > 0 && handler.scans() >= o.max_scans) break;
  }
  server.close_all();
  g_server = nullptr;
  if (!o.quiet)
    fmt::print("facetscan serve: {} scan(s), {} connection(s), {} disconnect(s)\n", handler.scans(),
               server.stats().connections, server.stats().disconnects);
}

// Where the shipped scenes are: next to the sources, or installed.
stdfs::path scenes_dir() {
  for (const stdfs::path& p : {stdfs::path(FACETSCAN_SCENES_DIR), stdfs::path("/usr/share/facetscan/scenes")})
    if (stdfs::is_directory(p)) return p;
  throw Error("cannot find the shipped scenes (looked in " FACETSCAN_SCENES_DIR
              " and /usr/share/facetscan/scenes)");
}

stdfs::path self_dir() {
  std::error_code ec;
  const stdfs::path exe = stdfs::read_symlink("/proc/self/exe", ec);
  return ec ? stdfs::current_path() : exe.parent_path();
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
  stdfs::create_directories(o.out_dir);
  const std::string recording = (stdfs::path(o.out_dir) / "scan.fscan").string();

  ScanHandler handler(library, rec::RecognizeParams{}, o.out_dir, o.quiet);
  StreamServerOptions so;
  so.listen = "127.0.0.1:0";
  so.reconnect_grace_ms = 2000;
  StreamServer server(so, [&](const Scan& s) { handler(s); });
  server.start();

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
  if (handler.scans() == 0)
    throw Error("the demo received no scan from facetscan-fw (exit code " + std::to_string(fw_code) + ")");
  return fw_code;
}

}  // namespace

void add_live_commands(CLI::App& app) {
  auto so = std::make_shared<ServeOptions>();
  auto* serve = app.add_subcommand("serve", "Listen for scanners and recognize every scan they stream");
  serve->add_option("--listen", so->listen, "ADDR:PORT to listen on (default 127.0.0.1:7450)");
  serve->add_option("-l,--library", so->library, "Library: a .fslib file, or mesh files / directories")
      ->required()
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
  serve->add_flag("-q,--quiet", so->quiet, "Print nothing per scan");
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
  demo->callback([o] {
    const int code = run_demo(*o);
    // With an injected fault the firmware is expected to stop in its fault state.
    if (code != 0 && o->faults.empty())
      throw Error(fmt::format("facetscan-fw ended with exit code {}", code));
  });
}

}  // namespace fs::host::cli
