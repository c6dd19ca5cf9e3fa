#pragma once
// facetscan-fw configuration: a JSON file (--config) and/or command-line flags (flags win).
//   {
//     "galvo": "sim" | "sim-can[:...]" | "gpio:..." | "can:...",   "camera": "sim" | "v4l2:...",
//     "laser": "gpio:CHIP:line=L[,active_low=1]"   (a laser on its own GPIO line, e.g. with the CAN galvo)
//     "scene": "hw-sim/scenes/cube.json",  "steps": 500,  "first_step": 0,  "scan_id": 1,
//     "stream": "HOST:PORT",  "record": "scan.fscan",  "rt": false,  "rt_priority": 80,  "rt_cpu": -1,
//     "rt_cpu_latency_us": 0 (PM QoS wake-up latency limit with rt; -1 = leave the CPU idle states alone),
//     "virtual_time": true,  "faults": ["galvo.stall@step=120"],
//     "loop": {"period_us": 500, "max_dwell_ms": 40, "camera_timeout_ms": 25, "late_limit_us": 250,
//              "max_consecutive_late": 3, "heartbeat_ms": 500, "require_host": false, "host_grace_ms": 0,
//              "homing_timeout_ms": 2000, "move_timeout_ms": 50},
//     "extract": {"method": "gauss-ml" | "gauss-log" | "gauss-fit" | "blais-rioux" | "gauss3" | "cog",
//     "min_contrast": 24,
//                 "read_noise": 1.5, "shot_noise": 0.35, "speckle": 0.12 (gauss-ml noise model),
//                 "ambiguous_ratio": 0.5, "saturation_run": 3, "along_stripe": 15 (rows of the along-stripe
//                 refinement: 0 = off, odd 3..15), "prefetch_rows": 16 (software prefetch distance: 0 = off,
//                 <= 1024)},
//     "sim_camera": {"period_us": 5000, "exposure_us": 1000, "readout_us": 1000, "buffers": 4,
//                    "speckle_grain_px": 0 (correlation length of the simulated speckle, 0..8; 0 = per
//                    pixel)},
//     "stream_buffer_kb": 16384, "host_heartbeat_timeout_ms": 0, "stream_drain_ms": 2000
//   }
// Unknown keys and wrong types are errors: fs::Error "<file>: <field>: <problem>".
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "firmware/loop/controller.hpp"

namespace fs::fw {

// The largest sim_camera.speckle_grain_px accepted (= sim::kMaxSpeckleGrainPx, checked where both are seen).
constexpr double kMaxSimSpeckleGrainPx = 8.0;

struct FwConfig {
  std::string galvo = "sim";
  std::string camera = "sim";
  std::string laser;   // "gpio:CHIP:line=L[,active_low=1]"; empty: the galvo's laser= line / the twin
  std::string scene;   // empty: the shipped default scene
  std::string stream;  // HOST:PORT
  std::string record;  // .fscan path
  bool rt = false;
  int rt_priority = 80;
  int rt_cpu = -1;
  int rt_cpu_latency_us = 0;
  std::optional<bool> virtual_time;  // default: virtual with sim devices, real time otherwise
  std::vector<std::string> faults;
  LoopConfig loop;
  std::uint32_t sim_period_us = 5000, sim_exposure_us = 1000, sim_readout_us = 1000, sim_buffers = 4;
  double sim_speckle_grain_px = 0.0;  // sim::RenderOptions::speckle_grain_px of the simulated camera's frames
  std::uint32_t stream_buffer_kb = 16384;
  std::uint32_t host_heartbeat_timeout_ms = 0;  // 0: host heartbeats not required
  std::uint32_t stream_drain_ms = 2000;  // at the end, how long the host may take to read what is queued
  bool steps_given = false;
};

// Applies a JSON document to cfg. `source` names it in errors.
void apply_config_json(FwConfig& cfg, const std::string& text, const std::string& source);
void load_config_file(FwConfig& cfg, const std::string& path);

}  // namespace fs::fw
