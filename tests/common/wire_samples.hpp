#pragma once
// Sample messages with every field set to a distinct value, for round-trip tests.
#include <vector>

#include "common/messages.hpp"

namespace fs::test {

inline msg::ScanBegin sample_scan_begin() {
  msg::ScanBegin m;
  m.scan_id = 0x0102030405060708ull;
  m.scanner_model = "facetscan-bench-1";
  m.calibration = ScannerCalibration::bench_default(321);
  m.calibration.camera.k1 = -0.125;
  m.calibration.camera.k2 = 0.0625;
  m.calibration.camera.k3 = -0.001;
  m.calibration.camera.p1 = 1e-4;
  m.calibration.camera.p2 = -2e-4;
  m.calibration.camera.R_world_cam(0, 1) = 0.25;  // distinct entries catch row/column swaps
  m.calibration.first_step = -17;
  m.calibration.table = Plane{Vec3(0.0, 0.6, 0.8), 3.5};
  m.pixel_bits = 16;
  m.units = "mm";
  m.start_time_ns = -123456789012345ll;
  return m;
}

inline std::vector<msg::StripePoint> sample_points(std::size_t n) {
  std::vector<msg::StripePoint> p(n);
  for (std::size_t i = 0; i < n; ++i) {
    p[i].row = static_cast<std::uint16_t>(i);
    p[i].col = 100.0f + 0.37f * static_cast<float>(i);
    p[i].peak = static_cast<std::uint16_t>(200 + (i * 7) % 50);
    p[i].width = 2.0f + 0.01f * static_cast<float>(i % 100);
  }
  return p;
}

inline msg::StripeHeader sample_stripe_header(std::uint32_t step) {
  msg::StripeHeader h;
  h.scan_id = 42;
  h.step_index = step;
  h.commanded_angle = -0.1 + 1e-4 * step;
  h.measured_position = step + 0.25;
  h.capture_time_ns = 1'000'000'000ll + 3'000'000ll * step;
  h.frame_sequence = 1000 + step;
  h.flags = 3;
  return h;
}

inline msg::ScanEnd sample_scan_end() {
  msg::ScanEnd m;
  m.scan_id = 42;
  m.stripes_sent = 500;
  m.frames_captured = 502;
  m.frames_dropped = 2;
  m.stripes_dropped = 1;
  m.fault_count = 3;
  m.last_fault_code = 0xBEEF;
  m.completed = 1;
  m.loop = {-5, 1200, 8000, 15000, 22000, 4, 350000, 900000};
  return m;
}

inline msg::Heartbeat sample_heartbeat() { return msg::Heartbeat{987654321, 77, 3}; }
inline msg::Fault sample_fault() { return msg::Fault{17, "galvo following error 12 steps"}; }

}  // namespace fs::test
