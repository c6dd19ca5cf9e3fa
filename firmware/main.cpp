// facetscan-fw and facetscan-fw-hil: the scanner board's firmware (galvo, laser, camera, stripe extraction,
// streaming). One main and one run_scan for both; the devices come from make_devices
// (firmware/app/devices.hpp), linked per binary: facetscan-fw has the real backends only (it ships on the
// board), facetscan-fw-hil adds the twins (hw-sim/devices_hil.cpp) and the sim-frame subcommand.
//   facetscan-fw-hil --scene hw-sim/scenes/cube.json --steps 300 --record cube.fscan      (HIL on the twins)
//   facetscan-fw-hil --galvo sim-can --record scan.fscan --fault camera.drop@frame=40
//   facetscan-fw-hil sim-frame --scene hw-sim/scenes/default.json --step 250 -o f.png
//   facetscan-fw --galvo gpio:gpiochip0:step=17,dir=27,en=22,home=23,laser=24 --camera v4l2:/dev/video0
//                --stream 192.168.1.10:5555 --rt   (one command line)
//   facetscan-fw --galvo can:can0:node=1 --camera v4l2:/dev/video0 --laser gpio:gpiochip0:line=24
//                --record s.fscan
//   facetscan-fw --check --galvo can:can0 --camera v4l2:/dev/video0 --laser gpio:gpiochip0:line=24
#include <fmt/core.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "common/error.hpp"
#include "common/scan_file.hpp"
#include "facetscan_version.hpp"
#include "firmware/app/devices.hpp"
#include "firmware/fw_config.hpp"
#include "firmware/loop/controller.hpp"
#include "firmware/loop/realtime.hpp"
#include "firmware/loop/safety.hpp"
#include "firmware/stream/queued_publisher.hpp"
#include "firmware/stream/tcp_sink.hpp"

namespace {

using namespace fs;

// Exit status of a scan (also documented in docs/firmware.md): 0 complete, 1 bad input, 2 fatal fault,
// 3 --check found a device missing, 4 streaming was requested and stripes did not reach the host (the scan
// itself completed; a fatal fault takes precedence: 2).
constexpr int kExitUndelivered = 4;

// "2 s", "500 ms": the drain time as the summary names it.
std::string drain_text(std::uint32_t ms) {
  return ms % 1000 == 0 ? std::to_string(ms / 1000) + " s" : std::to_string(ms) + " ms";
}

class NullSink final : public wire::FrameSink {
 public:
  void write(std::span<const std::uint8_t> b) override { bytes += b.size(); }
  std::uint64_t bytes = 0;
};

// The recording's sink while streaming: every frame goes to the file except ScanEnd, which is held back and
// written last (finish_recording) with the final count of stripes the host did not get, known only once the
// stream has been drained. Runs on the publisher's output thread.
class HoldEndSink final : public wire::FrameSink {
 public:
  explicit HoldEndSink(wire::FrameSink& file) : file_(file) { held_.reserve(wire::kMaxFrameSize); }
  void write(std::span<const std::uint8_t> b) override {
    if (b.size() > 6 && b[6] == static_cast<std::uint8_t>(msg::Type::ScanEnd)) {
      held_.assign(b.begin(), b.end());
      return;
    }
    file_.write(b);
  }
  // Writes the held ScanEnd with stripes_dropped = `undelivered`, preceded by a Fault 102 message `text`
  // when there were undelivered stripes; keeps the frame sequence continuous.
  void finish_recording(std::uint32_t undelivered, const std::string& text) {
    if (held_.empty()) return;
    wire::FrameDecoder dec("recording");
    std::span<const std::uint8_t> in(held_);
    in = in.subspan(dec.feed(in));
    wire::FrameView f;
    if (!dec.next(f)) return;
    wire::DecodedMessage m;
    wire::decode(f, m, "recording");
    msg::ScanEnd e = m.scan_end;
    e.stripes_dropped = std::max(e.stripes_dropped, undelivered);
    wire::FrameWriter w(file_, f.header.sequence);
    if (undelivered > 0) {
      msg::Fault fm;
      fm.code = static_cast<std::uint32_t>(fw::FaultCode::StripesDropped);
      fm.text = text.substr(0, msg::kMaxFaultText);
      w.send(fm);
      ++e.fault_count;
    }
    w.send(e);
  }

 private:
  wire::FrameSink& file_;
  std::vector<std::uint8_t> held_;
};

// What reached the host (streaming only).
struct StreamOutcome {
  bool requested = false;
  std::uint32_t produced = 0, undelivered = 0, connections = 0;
  std::string error;  // the last link error, or why the end was not delivered
};

// The end-of-scan summary on stderr.
void print_report(const fw::LoopReport& rep, const fw::FwConfig& cfg, bool virtual_time,
                  const ScanFileWriter* file, const StreamOutcome& so) {
  const msg::LoopStats s = rep.stats();
  std::fprintf(
      stderr,
      "%s: %s%s%s | stripes %u/%u, frames captured %u, dropped %u, stale %u, stripes dropped %u\n"
      "  loop (%s time, period %.0f us, %llu ticks): lateness min %.1f us, median %.1f us, p99 %.1f us, "
      "p99.9 %.1f us, max %.1f us, overruns %u\n"
      "  extraction: mean %.1f us, max %.1f us per frame (%u frames)\n",
      fw::program_name(), fw::to_string(rep.state), rep.fault != fw::FaultCode::None ? ": " : "",
      rep.fault != fw::FaultCode::None ? fw::to_string(rep.fault) : "", rep.stripes_sent, cfg.loop.steps,
      rep.frames_captured, rep.frames_dropped, rep.frames_stale,
      so.requested ? std::max(rep.stripes_dropped, so.undelivered) : rep.stripes_dropped,
      virtual_time ? "virtual" : "real", cfg.loop.period / 1e3, static_cast<unsigned long long>(rep.ticks),
      s.lateness_min_ns / 1e3, s.lateness_median_ns / 1e3, s.lateness_p99_ns / 1e3, s.lateness_p999_ns / 1e3,
      s.lateness_max_ns / 1e3, s.overruns, s.extraction_mean_ns / 1e3, s.extraction_max_ns / 1e3,
      rep.extractions);
  if (!virtual_time)
    std::fprintf(
        stderr,
        "  wake-ups (slept until the deadline): %llu, lateness median %.1f us, p99 %.1f us, p99.9 %.1f us, "
        "max %.1f us; %llu ticks started late without sleeping (the previous tick overran)\n",
        static_cast<unsigned long long>(rep.wakeup.count()), rep.wakeup.quantile(0.5) / 1e3,
        rep.wakeup.quantile(0.99) / 1e3, rep.wakeup.quantile(0.999) / 1e3, rep.wakeup.max() / 1e3,
        static_cast<unsigned long long>(rep.ticks_without_sleep));
  // Every fault with its step and, for the fatal ones, the laser-off latency the loop measured.
  char lat[160];
  for (std::uint32_t i = 0; i < rep.fault_events_n; ++i) {
    const fw::FaultEvent& e = rep.fault_events[i];
    if (fw::is_fatal(e.code)) {
      fw::format_laser_off(lat, sizeof lat, e, cfg.loop.period);
      std::fprintf(stderr, "  fault %u %s at step %u (state %s): %s\n", static_cast<unsigned>(e.code),
                   fw::to_string(e.code), e.step, fw::to_string(e.state), lat);
    } else {
      std::fprintf(stderr, "  warning %u %s at step %u\n", static_cast<unsigned>(e.code),
                   fw::to_string(e.code), e.step);
    }
  }
  if (rep.max_laser_off_latency_ns >= 0)
    std::fprintf(stderr, "  laser-off latency max %.2f ms (period %.2f ms)\n",
                 rep.max_laser_off_latency_ns / 1e6, cfg.loop.period / 1e6);
  if (so.requested) {
    if (so.undelivered == 0)
      std::fprintf(stderr, "  stream %s: all %u stripes delivered (%u connection(s))\n", cfg.stream.c_str(),
                   so.produced, so.connections);
    else
      std::fprintf(stderr, "%s: error: %u of %u stripes undelivered to %s: %s\n", fw::program_name(),
                   so.undelivered, so.produced, cfg.stream.c_str(), so.error.c_str());
  }
  if (file)
    std::fprintf(stderr, "  recorded %s (%llu bytes)\n", cfg.record.c_str(),
                 static_cast<unsigned long long>(file->bytes_written()));
}

int run_scan(fw::FwConfig& cfg) {
  // Declared first: the devices outlive the controller, the safety guard and the publisher.
  const std::unique_ptr<fw::ScanDevices> dev = fw::make_devices(cfg);
  const ScannerCalibration& cal = dev->calibration;
  const bool virtual_time = dev->virtual_time;

  // Output: recording and/or stream.
  std::unique_ptr<ScanFileWriter> file;
  std::unique_ptr<fw::TcpSink> tcp;
  std::unique_ptr<HoldEndSink> hold;
  NullSink null_sink;
  wire::FrameSink* sink = &null_sink;
  if (!cfg.record.empty()) file = std::make_unique<ScanFileWriter>(cfg.record);
  if (!cfg.stream.empty()) {
    fw::TcpSinkConfig tc;
    tc.buffer_bytes = static_cast<std::size_t>(cfg.stream_buffer_kb) * 1024;
    tc.host_heartbeat_timeout = static_cast<fw::Nanos>(cfg.host_heartbeat_timeout_ms) * 1'000'000;
    tcp = std::make_unique<fw::TcpSink>(cfg.stream, tc);
    // Resolve once at start: a name that does not resolve is reported now, not only at the end. The scan
    // goes on and the sink keeps retrying (a board may boot before its network or DNS is up); its stripes
    // count as undelivered until the host takes them (exit status 4 when some never do).
    const std::string rerr = fw::resolve_error(tcp->host(), tcp->port());
    if (!rerr.empty())
      std::fprintf(stderr, "%s: warning: stream: %s (retrying in the background)\n", fw::program_name(),
                   rerr.c_str());
  }
  std::unique_ptr<wire::TeeSink> tee;
  if (file && tcp) {
    hold = std::make_unique<HoldEndSink>(*file);
    tee = std::make_unique<wire::TeeSink>(*hold, *tcp);
    sink = tee.get();
  } else if (file) {
    sink = file.get();
  } else if (tcp) {
    sink = tcp.get();
  }
  fw::QueuedPublisherConfig pc;
  pc.max_points = cal.camera.height;
  pc.slots = 256;
  pc.block_when_full = virtual_time && !tcp;
  fw::QueuedPublisher pub(*sink, pc, tcp.get());

  fw::Controller ctl(dev->devices(), cfg.loop, pub, cal);
  fw::SafetyGuard guard(*dev->laser, *dev->galvo, &ctl);
  fw::RealtimeResult rt;  // holds the CPU latency limit until the scan ends
  if (cfg.rt) {
    fw::RealtimeRequest rq;
    rq.priority = cfg.rt_priority;
    rq.cpu = cfg.rt_cpu;
    rq.cpu_latency_us = cfg.rt_cpu_latency_us;
    rt = fw::apply_realtime(rq);
    for (const auto& w : rt.warnings)
      std::fprintf(stderr, "%s: warning: %s\n", fw::program_name(), w.c_str());
  }
  const fw::LoopReport& rep = ctl.run();
  pub.flush();
  StreamOutcome so;
  if (tcp) {
    // Hand the last frames (the final stripes and ScanEnd) to the host before the process exits; what the
    // host has not acknowledged after stream_drain_ms is undelivered.
    const bool drained = tcp->drain(static_cast<fw::Nanos>(cfg.stream_drain_ms) * 1'000'000);
    const std::size_t left = tcp->buffered_bytes();
    const bool connected = tcp->connected();
    tcp->close();
    so.requested = true;
    so.produced = rep.stripes_sent + pub.ring_dropped();
    so.undelivered = so.produced - std::min(so.produced, tcp->stripes_delivered());
    so.connections = tcp->connections();
    so.error = tcp->last_error();
    if (so.undelivered > 0 && connected && !drained)  // connected, but the host stopped reading
      so.error = "the host did not take the stream (" + std::to_string(left) + " bytes still queued after " +
                 drain_text(cfg.stream_drain_ms) + ", stripes unacknowledged)";
    else if (so.undelivered > 0 && so.error.empty())
      so.error = "not connected";
    if (hold) {
      char text[msg::kMaxFaultText];
      std::snprintf(text, sizeof text, "%s: %u of %u stripes undelivered to %s: %s",
                    fw::to_string(fw::FaultCode::StripesDropped), so.undelivered, so.produced,
                    cfg.stream.c_str(), so.error.c_str());
      hold->finish_recording(so.undelivered, text);
    }
  }
  if (file) file->close();

  print_report(rep, cfg, virtual_time, file.get(), so);
  if (rep.state != fw::State::Done) return 2;
  return so.undelivered > 0 ? kExitUndelivered : 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string name = fw::program_name();
  CLI::App app{name + ": laser-stripe scanner firmware (controller loop, stripe extraction, streaming)" +
               (fw::has_twins() ? ", on the simulated devices" : "")};
  app.set_version_flag("--version", name + " " + fs::kVersion);
  fw::FwConfig cfg;
  std::string config_path;
  std::uint32_t steps = 0;
  bool realtime = false, virtual_time = false, check = false;
  app.add_option("--config", config_path, "JSON configuration file (flags override it)")
      ->check(CLI::ExistingFile);
  const bool twins = fw::has_twins();
  // The twins' options are hidden in the board binary (it refuses them with a message naming
  // facetscan-fw-hil).
  const std::string sim_group = twins ? "Options" : "";
  app.add_option("--galvo", cfg.galvo,
                 std::string(twins ? "sim | sim-can[:node=N,...] | " : "") +
                     "gpio:CHIP:step=L,dir=L,en=L,home=L[,laser=L] | can:IFACE[:...]");
  app.add_option("--camera", cfg.camera,
                 std::string(twins ? "sim | " : "") + "v4l2:/dev/videoN[:fmt=GREY,...]");
  app.add_option("--laser", cfg.laser,
                 "gpio:CHIP:line=L[,active_low=1] (a laser on its own line, e.g. with --galvo can:...)");
  app.add_option("--scene", cfg.scene,
                 "scene JSON for the simulated camera (default: the shipped default scene)")
      ->group(sim_group);
  app.add_option("--steps", steps, "number of galvo steps of the scan")->check(CLI::Range(1, 100000));
  std::uint64_t scan_id = 1;
  app.add_option("--scan-id", scan_id,
                 "the scan's id in ScanBegin (default 1): a board numbers its scans, a simulated scanner "
                 "repeating a scene gives each scan its own")
      ->check(CLI::Range(std::uint64_t{1}, std::uint64_t{1} << 62));
  app.add_option("--stream", cfg.stream, "stream to the host HOST:PORT (reconnects with backoff)");
  app.add_option("--record", cfg.record, "record the scan to a .fscan file");
  app.add_flag(
      "--rt", cfg.rt,
      "SCHED_FIFO + mlockall + CPU affinity + CPU wake-up latency limit for the loop (warns when not "
      "permitted)");
  app.add_option("--fault", cfg.faults,
                 "inject a fault into the twins, e.g. galvo.stall@step=120 (repeatable)")
      ->group(sim_group);
  app.add_flag(
      "--check", check,
      "probe the configured devices (GPIO chip/lines, CAN drive, camera formats), print what is found and "
      "what is missing; exit 0 only when everything is there (3 otherwise)");
  auto* rt_opt = app.add_flag("--realtime", realtime, "run the twins in real time")->group(sim_group);
  app.add_flag("--virtual-time", virtual_time, "run the twins on virtual time (default with sim devices)")
      ->excludes(rt_opt)
      ->group(sim_group);
  fw::add_device_commands(app);
  app.require_subcommand(0, 1);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const fs::Error& e) {
    std::fprintf(stderr, "%s: error: %s\n", fw::program_name(), e.what());
    return 1;
  }
  if (!app.get_subcommands().empty()) return 0;  // a subcommand (sim-frame) ran in its callback
  try {
    fw::FwConfig flags = cfg;
    if (!config_path.empty()) {
      fw::FwConfig fromfile;
      fw::load_config_file(fromfile, config_path);
      // Flags given on the command line win over the file.
      if (app.count("--galvo")) fromfile.galvo = flags.galvo;
      if (app.count("--camera")) fromfile.camera = flags.camera;
      if (app.count("--laser")) fromfile.laser = flags.laser;
      if (app.count("--scene")) fromfile.scene = flags.scene;
      if (app.count("--stream")) fromfile.stream = flags.stream;
      if (app.count("--record")) fromfile.record = flags.record;
      if (app.count("--rt")) fromfile.rt = true;
      if (app.count("--fault"))
        fromfile.faults.insert(fromfile.faults.end(), flags.faults.begin(), flags.faults.end());
      cfg = fromfile;
    }
    if (app.count("--steps")) {
      cfg.loop.steps = steps;
      cfg.steps_given = true;
    }
    if (app.count("--scan-id")) cfg.loop.scan_id = scan_id;
    if (realtime) cfg.virtual_time = false;
    if (virtual_time) cfg.virtual_time = true;
    if (check) {
      const fw::CheckReport r = fw::check_configured_devices(cfg);
      std::fputs(r.text().c_str(), stdout);
      if (r.ok()) {
        std::printf("%s --check: all %zu checks passed\n", fw::program_name(), r.items.size());
        return 0;
      }
      std::printf("%s --check: %zu of %zu checks failed (MISS above)\n", fw::program_name(), r.failed(),
                  r.items.size());
      return 3;
    }
    return run_scan(cfg);
  } catch (const fs::Error& e) {
    std::fprintf(stderr, "%s: error: %s\n", fw::program_name(), e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: error: %s\n", fw::program_name(), e.what());
    return 1;
  }
}
