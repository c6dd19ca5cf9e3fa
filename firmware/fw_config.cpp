#include "firmware/fw_config.hpp"

#include <nlohmann/json.hpp>

#include "common/error.hpp"
#include "common/input_file.hpp"
#include "common/json_text.hpp"
#include "firmware/extract/along_stripe.hpp"

namespace fs::fw {

namespace {

using json = nlohmann::json;

[[noreturn]] void bad(const std::string& source, const std::string& field, const std::string& what) {
  throw Error(source + ": " + field + ": " + what);
}

template <typename T>
T get_num(const json& j, const std::string& source, const std::string& field, double lo, double hi) {
  if (!j.is_number()) bad(source, field, "expected a number");
  const double v = j.get<double>();
  if (!(v >= lo && v <= hi))
    bad(source, field, "out of range [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  if constexpr (std::is_integral_v<T>) {
    if (v != static_cast<double>(static_cast<std::int64_t>(v))) bad(source, field, "expected an integer");
  }
  return static_cast<T>(v);
}

std::string get_str(const json& j, const std::string& source, const std::string& field) {
  if (!j.is_string()) bad(source, field, "expected a string");
  return j.get<std::string>();
}

bool get_bool(const json& j, const std::string& source, const std::string& field) {
  if (!j.is_boolean()) bad(source, field, "expected true or false");
  return j.get<bool>();
}

}  // namespace

void apply_config_json(FwConfig& c, const std::string& text, const std::string& src) {
  const json doc = parse_json_text(text, src);
  if (!doc.is_object()) bad(src, "(top level)", "expected an object");
  for (const auto& [k, v] : doc.items()) {
    if (k == "galvo")
      c.galvo = get_str(v, src, k);
    else if (k == "camera")
      c.camera = get_str(v, src, k);
    else if (k == "laser")
      c.laser = get_str(v, src, k);
    else if (k == "scene")
      c.scene = get_str(v, src, k);
    else if (k == "stream")
      c.stream = get_str(v, src, k);
    else if (k == "record")
      c.record = get_str(v, src, k);
    else if (k == "rt")
      c.rt = get_bool(v, src, k);
    else if (k == "rt_priority")
      c.rt_priority = get_num<int>(v, src, k, 1, 99);
    else if (k == "rt_cpu")
      c.rt_cpu = get_num<int>(v, src, k, -1, 1023);
    else if (k == "rt_cpu_latency_us")
      c.rt_cpu_latency_us = get_num<int>(v, src, k, -1, 2'000'000'000);
    else if (k == "virtual_time")
      c.virtual_time = get_bool(v, src, k);
    else if (k == "steps") {
      c.loop.steps = get_num<std::uint32_t>(v, src, k, 1, 100000);
      c.steps_given = true;
    } else if (k == "scan_id")
      c.loop.scan_id = get_num<std::uint64_t>(v, src, k, 1, 4.6e18);
    else if (k == "first_step")
      c.loop.first_step = get_num<std::int32_t>(v, src, k, -1e6, 1e6);
    else if (k == "stream_buffer_kb")
      c.stream_buffer_kb = get_num<std::uint32_t>(v, src, k, 64, 1 << 20);
    else if (k == "host_heartbeat_timeout_ms")
      c.host_heartbeat_timeout_ms = get_num<std::uint32_t>(v, src, k, 0, 3.6e6);
    else if (k == "stream_drain_ms")
      c.stream_drain_ms = get_num<std::uint32_t>(v, src, k, 0, 3.6e6);
    else if (k == "faults") {
      if (!v.is_array()) bad(src, k, "expected an array of fault specs");
      c.faults.clear();
      for (std::size_t i = 0; i < v.size(); ++i)
        c.faults.push_back(get_str(v[i], src, k + "[" + std::to_string(i) + "]"));
    } else if (k == "loop") {
      if (!v.is_object()) bad(src, k, "expected an object");
      LoopConfig& l = c.loop;
      for (const auto& [lk, lv] : v.items()) {
        const std::string f = "loop." + lk;
        if (lk == "period_us")
          l.period = get_num<Nanos>(lv, src, f, 50, 1e6) * 1000;
        else if (lk == "max_dwell_ms")
          l.max_dwell = get_num<Nanos>(lv, src, f, 1, 1e5) * 1'000'000;
        else if (lk == "camera_timeout_ms")
          l.camera_timeout = get_num<Nanos>(lv, src, f, 1, 1e5) * 1'000'000;
        else if (lk == "late_limit_us")
          l.late_limit = get_num<Nanos>(lv, src, f, 1, 1e6) * 1000;
        else if (lk == "max_consecutive_late")
          l.max_consecutive_late = get_num<std::uint32_t>(lv, src, f, 0, 1e6);
        else if (lk == "heartbeat_ms")
          l.heartbeat_period = get_num<Nanos>(lv, src, f, 1, 1e6) * 1'000'000;
        else if (lk == "require_host")
          l.require_host = get_bool(lv, src, f);
        else if (lk == "host_grace_ms")
          l.host_grace = get_num<Nanos>(lv, src, f, 0, 1e6) * 1'000'000;
        else if (lk == "homing_timeout_ms")
          l.homing_timeout = get_num<Nanos>(lv, src, f, 1, 1e6) * 1'000'000;
        else if (lk == "move_timeout_ms")
          l.move_timeout = get_num<Nanos>(lv, src, f, 1, 1e6) * 1'000'000;
        else
          bad(src, f, "unknown key");
      }
    } else if (k == "extract") {
      if (!v.is_object()) bad(src, k, "expected an object");
      ExtractParams& e = c.loop.extract;
      for (const auto& [ek, ev] : v.items()) {
        const std::string f = "extract." + ek;
        if (ek == "method") {
          const std::string m = get_str(ev, src, f);
          try {
            e.method = parse_subpixel_method(m.c_str());
          } catch (const Error& err) {
            bad(src, f, err.what());
          }
        } else if (ek == "min_contrast")
          e.min_contrast = get_num<double>(ev, src, f, 1, 255);
        else if (ek == "ambiguous_ratio")
          e.ambiguous_ratio = get_num<double>(ev, src, f, 0.05, 1);
        else if (ek == "saturation_run")
          e.saturation_run = get_num<std::uint32_t>(ev, src, f, 1, 1000);
        else if (ek == "read_noise")
          e.read_noise = get_num<double>(ev, src, f, 0, 1000);
        else if (ek == "shot_noise")
          e.shot_noise = get_num<double>(ev, src, f, 0, 100);
        else if (ek == "speckle")
          e.speckle = get_num<double>(ev, src, f, 0, 10);
        else if (ek == "along_stripe") {
          const auto rows = get_num<std::uint32_t>(ev, src, f, 0, kAlongStripeMaxRows);
          if (rows > 1 && rows % 2 == 0) bad(src, f, "expected 0 or 1 (off) or an odd number of rows 3..15");
          e.along_stripe = rows;
        } else if (ek == "prefetch_rows")
          e.prefetch_rows = get_num<std::uint32_t>(ev, src, f, 0, 1024);
        else
          bad(src, f, "unknown key");
      }
    } else if (k == "sim_camera") {
      if (!v.is_object()) bad(src, k, "expected an object");
      for (const auto& [sk, sv] : v.items()) {
        const std::string f = "sim_camera." + sk;
        if (sk == "period_us")
          c.sim_period_us = get_num<std::uint32_t>(sv, src, f, 100, 1e6);
        else if (sk == "exposure_us")
          c.sim_exposure_us = get_num<std::uint32_t>(sv, src, f, 1, 1e6);
        else if (sk == "readout_us")
          c.sim_readout_us = get_num<std::uint32_t>(sv, src, f, 0, 1e6);
        else if (sk == "buffers")
          c.sim_buffers = get_num<std::uint32_t>(sv, src, f, 2, 32);
        else if (sk == "speckle_grain_px")
          c.sim_speckle_grain_px = get_num<double>(sv, src, f, 0, kMaxSimSpeckleGrainPx);
        else
          bad(src, f, "unknown key");
      }
    } else {
      bad(src, k, "unknown key");
    }
  }
}

void load_config_file(FwConfig& cfg, const std::string& path) {
  apply_config_json(cfg, read_input_file(path, kMaxConfigFileBytes, "firmware configuration"), path);
}

}  // namespace fs::fw
