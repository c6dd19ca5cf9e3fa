#pragma once
// Scanner -> host messages (the payloads of wire frames; encoding lives in common/wire.hpp).
// Every field is encoded explicitly, little-endian; see docs/formats.md, "Wire protocol".
#include <array>
#include <cstdint>
#include <span>
#include <string>

#include "common/calibration.hpp"

namespace fs::msg {

enum class Type : std::uint8_t { ScanBegin = 1, Stripe = 2, ScanEnd = 3, Heartbeat = 4, Fault = 5 };

inline constexpr std::size_t kMaxModelName = 64;
inline constexpr std::size_t kMaxFaultText = 256;
inline constexpr std::uint32_t kMaxStripePoints = 8192;

struct ScanBegin {
  std::uint64_t scan_id = 0;
  std::string scanner_model;       // <= kMaxModelName bytes
  ScannerCalibration calibration;  // camera intrinsics + distortion + pose, laser/galvo, steps
  std::uint8_t pixel_bits = 8;     // 8 or 16
  std::string units = "mm";        // lengths in the calibration
  std::int64_t start_time_ns = 0;
};

// One image row's stripe peak.
struct StripePoint {
  std::uint16_t row = 0;   // image row
  float col = 0.0f;        // sub-pixel column of the stripe centre (distorted pixel coordinates)
  std::uint16_t peak = 0;  // peak intensity (raw sensor units)
  float width = 0.0f;      // stripe width in pixels (full width at half maximum)
};

struct StripeHeader {
  std::uint64_t scan_id = 0;
  std::uint32_t step_index = 0;      // galvo step k
  double commanded_angle = 0.0;      // mirror angle commanded for step k (rad)
  double measured_position = 0.0;    // galvo position read back (steps)
  std::int64_t capture_time_ns = 0;  // exposure timestamp (scanner's monotonic clock)
  std::uint32_t frame_sequence = 0;  // camera frame sequence number
  std::uint32_t flags = 0;           // bit 0: saturated rows present, bit 1: ambiguous rows present
};

// A stripe whose points live in caller-provided memory (decoding never allocates).
struct Stripe {
  StripeHeader header;
  std::span<StripePoint> points;
};

// Loop statistics of the firmware (wake-up lateness in ns).
struct LoopStats {
  std::int64_t lateness_min_ns = 0, lateness_median_ns = 0, lateness_p99_ns = 0, lateness_p999_ns = 0,
               lateness_max_ns = 0;
  std::uint32_t overruns = 0;
  std::int64_t extraction_mean_ns = 0, extraction_max_ns = 0;
};

struct ScanEnd {
  std::uint64_t scan_id = 0;
  std::uint32_t stripes_sent = 0;
  std::uint32_t frames_captured = 0;
  std::uint32_t frames_dropped = 0;  // camera sequence gaps + timeouts
  // Stripes that did not reach the host: on the stream, those known lost when the scan ended (queue and link
  // buffer overflow, lost in flight on a dropped connection); in a recording made while streaming, the final
  // count of stripes the host did not acknowledge (the recording's ScanEnd is written after the stream was
  // drained; docs/firmware.md, "Undelivered stripes").
  std::uint32_t stripes_dropped = 0;
  std::uint32_t fault_count = 0;
  std::uint32_t last_fault_code = 0;
  std::uint8_t completed = 0;  // 1 = all steps scanned, 0 = aborted
  LoopStats loop;
};

struct Heartbeat {
  std::int64_t time_ns = 0;
  std::uint64_t counter = 0;
  std::uint8_t state = 0;  // firmware state machine state
};

struct Fault {
  std::uint32_t code = 0;
  std::string text;  // <= kMaxFaultText bytes
};

}  // namespace fs::msg
