// The wire protocol (wire.hpp) in one file on purpose: the field checks, the encoder and the decoder of each
// message sit side by side so that a change to a message's layout is made in one place; FrameDecoder, at the
// end, reassembles frames from a byte stream for the TCP server and the .fscan reader.
#include "common/wire.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "common/byte_io.hpp"
#include "common/crc32c.hpp"

namespace fs::wire {

const char* type_name(msg::Type t) {
  switch (t) {
    case msg::Type::ScanBegin:
      return "ScanBegin";
    case msg::Type::Stripe:
      return "Stripe";
    case msg::Type::ScanEnd:
      return "ScanEnd";
    case msg::Type::Heartbeat:
      return "Heartbeat";
    case msg::Type::Fault:
      return "Fault";
  }
  return "unknown";
}

bool is_known_type(std::uint8_t t) { return t >= 1 && t <= 5; }

// ---- payload field lists
// -------------------------------------------------------------------------------------

namespace {

void put_vec3(ByteWriter& w, const Vec3& v) {
  w.put<double>(v.x());
  w.put<double>(v.y());
  w.put<double>(v.z());
}
// Calibration values must be usable: finite numbers, positive focal lengths, sane sizes.
double get_finite(ByteReader& r, const char* field) {
  const std::uint64_t at = r.offset();
  const double v = r.get<double>(field);
  if (!std::isfinite(v))
    throw r.fail_at(at, std::string("ScanBegin.") + field + " is not finite (" + std::to_string(v) + ")");
  return v;
}
double get_positive(ByteReader& r, const char* field) {
  const std::uint64_t at = r.offset();
  const double v = get_finite(r, field);
  if (!(v > 0.0))
    throw r.fail_at(at, std::string("ScanBegin.") + field + " must be > 0, is " + std::to_string(v));
  return v;
}
std::uint32_t get_in_range(ByteReader& r, const char* field, std::uint32_t lo, std::uint32_t hi) {
  const std::uint64_t at = r.offset();
  const auto v = r.get<std::uint32_t>(field);
  if (v < lo || v > hi)
    throw r.fail_at(at, std::string("ScanBegin.") + field + " is " + std::to_string(v) + ", expected " +
                            std::to_string(lo) + ".." + std::to_string(hi));
  return v;
}

Vec3 get_vec3(ByteReader& r, const char* field) {
  const double x = get_finite(r, field), y = get_finite(r, field), z = get_finite(r, field);
  return Vec3(x, y, z);
}

void put_calibration(ByteWriter& w, const ScannerCalibration& c) {
  const CameraModel& cam = c.camera;
  w.put<std::uint32_t>(cam.width);
  w.put<std::uint32_t>(cam.height);
  for (double v : {cam.fx, cam.fy, cam.cx, cam.cy, cam.k1, cam.k2, cam.k3, cam.p1, cam.p2}) w.put<double>(v);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) w.put<double>(cam.R_world_cam(i, j));
  put_vec3(w, cam.t_world_cam);
  const LaserModel& l = c.laser;
  put_vec3(w, l.axis_point);
  put_vec3(w, l.axis_dir);
  put_vec3(w, l.normal_at_zero);
  w.put<double>(l.optical_gain);
  w.put<double>(l.mirror_angle_at_step0);
  w.put<double>(l.rad_per_step);
  w.put<std::int32_t>(c.first_step);
  w.put<std::uint32_t>(c.step_count);
  put_vec3(w, c.table.n);
  w.put<double>(c.table.d);
}

void get_calibration(ByteReader& r, ScannerCalibration& c) {
  CameraModel& cam = c.camera;
  cam.width = get_in_range(r, "camera.width", 1, 65536);  // rows travel as u16
  cam.height = get_in_range(r, "camera.height", 1, 65536);
  cam.fx = get_positive(r, "camera.fx");
  cam.fy = get_positive(r, "camera.fy");
  cam.cx = get_finite(r, "camera.cx");
  cam.cy = get_finite(r, "camera.cy");
  cam.k1 = get_finite(r, "camera.k1");
  cam.k2 = get_finite(r, "camera.k2");
  cam.k3 = get_finite(r, "camera.k3");
  cam.p1 = get_finite(r, "camera.p1");
  cam.p2 = get_finite(r, "camera.p2");
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) cam.R_world_cam(i, j) = get_finite(r, "camera.R_world_cam");
  cam.t_world_cam = get_vec3(r, "camera.t_world_cam");
  LaserModel& l = c.laser;
  l.axis_point = get_vec3(r, "laser.axis_point");
  l.axis_dir = get_vec3(r, "laser.axis_dir");
  l.normal_at_zero = get_vec3(r, "laser.normal_at_zero");
  l.optical_gain = get_finite(r, "laser.optical_gain");
  l.mirror_angle_at_step0 = get_finite(r, "laser.mirror_angle_at_step0");
  l.rad_per_step = get_finite(r, "laser.rad_per_step");
  c.first_step = r.get<std::int32_t>("first_step");
  c.step_count = get_in_range(r, "step_count", 1, 1u << 24);
  c.table.n = get_vec3(r, "table.n");
  c.table.d = get_finite(r, "table.d");
}

void put_payload(ByteWriter& w, const msg::ScanBegin& m) {
  w.put<std::uint64_t>(m.scan_id);
  w.put_string(m.scanner_model, msg::kMaxModelName, "ScanBegin.scanner_model");
  put_calibration(w, m.calibration);
  w.put<std::uint8_t>(m.pixel_bits);
  w.put_string(m.units, kMaxUnitsLength, "ScanBegin.units");
  w.put<std::int64_t>(m.start_time_ns);
}

void put_payload(ByteWriter& w, const msg::Stripe& m) {
  if (m.points.size() > msg::kMaxStripePoints)
    throw Error("encode: Stripe has " + std::to_string(m.points.size()) + " points, maximum " +
                std::to_string(msg::kMaxStripePoints));
  const msg::StripeHeader& h = m.header;
  w.put<std::uint64_t>(h.scan_id);
  w.put<std::uint32_t>(h.step_index);
  w.put<double>(h.commanded_angle);
  w.put<double>(h.measured_position);
  w.put<std::int64_t>(h.capture_time_ns);
  w.put<std::uint32_t>(h.frame_sequence);
  w.put<std::uint32_t>(h.flags);
  w.put<std::uint32_t>(static_cast<std::uint32_t>(m.points.size()));
  // Points: one bounds check for the whole block, then raw little-endian stores.
  std::span<std::uint8_t> dst = w.rest();
  const std::size_t n = m.points.size() * kStripePointSize;
  w.skip(n);
  std::uint8_t* p = dst.data();
  for (const msg::StripePoint& pt : m.points) {
    store_le<std::uint16_t>(p, pt.row);
    store_le<float>(p + 2, pt.col);
    store_le<std::uint16_t>(p + 6, pt.peak);
    store_le<float>(p + 8, pt.width);
    p += kStripePointSize;
  }
}

void put_payload(ByteWriter& w, const msg::ScanEnd& m) {
  w.put<std::uint64_t>(m.scan_id);
  w.put<std::uint32_t>(m.stripes_sent);
  w.put<std::uint32_t>(m.frames_captured);
  w.put<std::uint32_t>(m.frames_dropped);
  w.put<std::uint32_t>(m.stripes_dropped);
  w.put<std::uint32_t>(m.fault_count);
  w.put<std::uint32_t>(m.last_fault_code);
  w.put<std::uint8_t>(m.completed);
  const msg::LoopStats& s = m.loop;
  w.put<std::int64_t>(s.lateness_min_ns);
  w.put<std::int64_t>(s.lateness_median_ns);
  w.put<std::int64_t>(s.lateness_p99_ns);
  w.put<std::int64_t>(s.lateness_p999_ns);
  w.put<std::int64_t>(s.lateness_max_ns);
  w.put<std::uint32_t>(s.overruns);
  w.put<std::int64_t>(s.extraction_mean_ns);
  w.put<std::int64_t>(s.extraction_max_ns);
}

void put_payload(ByteWriter& w, const msg::Heartbeat& m) {
  w.put<std::int64_t>(m.time_ns);
  w.put<std::uint64_t>(m.counter);
  w.put<std::uint8_t>(m.state);
}

void put_payload(ByteWriter& w, const msg::Fault& m) {
  w.put<std::uint32_t>(m.code);
  w.put_string(m.text, msg::kMaxFaultText, "Fault.text");
}

template <class M>
msg::Type type_of();
template <>
msg::Type type_of<msg::ScanBegin>() {
  return msg::Type::ScanBegin;
}
template <>
msg::Type type_of<msg::Stripe>() {
  return msg::Type::Stripe;
}
template <>
msg::Type type_of<msg::ScanEnd>() {
  return msg::Type::ScanEnd;
}
template <>
msg::Type type_of<msg::Heartbeat>() {
  return msg::Type::Heartbeat;
}
template <>
msg::Type type_of<msg::Fault>() {
  return msg::Type::Fault;
}

template <class M>
std::size_t encode_frame(std::span<std::uint8_t> out, std::uint32_t sequence, const M& m) {
  ByteWriter w(out);
  w.put_bytes(kMagic);
  w.put<std::uint8_t>(kProtocolMajor);
  w.put<std::uint8_t>(kProtocolMinor);
  w.put<std::uint8_t>(static_cast<std::uint8_t>(type_of<M>()));
  w.put<std::uint8_t>(0);
  w.put<std::uint32_t>(0);  // length, patched below
  w.put<std::uint32_t>(sequence);
  put_payload(w, m);
  const std::size_t payload = w.position() - kFrameHeaderSize;
  store_le<std::uint32_t>(out.data() + 8, static_cast<std::uint32_t>(payload));
  const std::uint32_t crc = crc32c(w.written());
  w.put<std::uint32_t>(crc);
  return w.position();
}

// Reader over a frame's payload with absolute offsets. At the end, the payload must be consumed exactly
// unless the frame has a newer minor version (whose extra fields this reader does not know).
struct PayloadReader : ByteReader {
  PayloadReader(const FrameView& f, const std::string& source, msg::Type expected)
      : ByteReader(f.payload, &source, f.offset + kFrameHeaderSize), frame(f) {
    if (f.header.type != expected)
      throw fail_at(f.offset + 6, std::string("frame type is ") + type_name(f.header.type) + ", expected " +
                                      type_name(expected));
  }
  void done() const {
    if (remaining() != 0 && frame.header.minor <= kProtocolMinor)
      throw fail(std::to_string(remaining()) + " unexpected trailing bytes in " +
                 type_name(frame.header.type) + " payload (protocol " + std::to_string(frame.header.major) +
                 "." + std::to_string(frame.header.minor) + ")");
  }
  const FrameView& frame;
};

}  // namespace

// ---- sizes and encode
// ---------------------------------------------------------------------------------------

std::size_t payload_size(const msg::ScanBegin& m) {
  return kScanBeginFixedSize + m.scanner_model.size() + m.units.size();
}
std::size_t payload_size(const msg::Stripe& m) {
  return kStripeHeaderSize + kStripePointSize * m.points.size();
}
std::size_t payload_size(const msg::ScanEnd&) { return kScanEndSize; }
std::size_t payload_size(const msg::Heartbeat&) { return kHeartbeatSize; }
std::size_t payload_size(const msg::Fault& m) { return 4 + 2 + m.text.size(); }

std::size_t encode(std::span<std::uint8_t> out, std::uint32_t seq, const msg::ScanBegin& m) {
  return encode_frame(out, seq, m);
}
std::size_t encode(std::span<std::uint8_t> out, std::uint32_t seq, const msg::Stripe& m) {
  return encode_frame(out, seq, m);
}
std::size_t encode(std::span<std::uint8_t> out, std::uint32_t seq, const msg::ScanEnd& m) {
  return encode_frame(out, seq, m);
}
std::size_t encode(std::span<std::uint8_t> out, std::uint32_t seq, const msg::Heartbeat& m) {
  return encode_frame(out, seq, m);
}
std::size_t encode(std::span<std::uint8_t> out, std::uint32_t seq, const msg::Fault& m) {
  return encode_frame(out, seq, m);
}

FrameWriter::FrameWriter(FrameSink& sink, std::uint32_t first_sequence, std::size_t max_frame)
    : sink_(sink), buffer_(max_frame), seq_(first_sequence) {}

// ---- decode payloads
// -----------------------------------------------------------------------------------------

void decode(const FrameView& f, msg::ScanBegin& m, const std::string& source) {
  PayloadReader r(f, source, msg::Type::ScanBegin);
  m.scan_id = r.get<std::uint64_t>("ScanBegin.scan_id");
  r.get_string(m.scanner_model, msg::kMaxModelName, "ScanBegin.scanner_model");
  get_calibration(r, m.calibration);
  const std::uint64_t at = r.offset();
  m.pixel_bits = r.get<std::uint8_t>("ScanBegin.pixel_bits");
  if (m.pixel_bits != 8 && m.pixel_bits != 16)
    throw r.fail_at(at, "ScanBegin.pixel_bits is " + std::to_string(m.pixel_bits) + ", expected 8 or 16");
  r.get_string(m.units, kMaxUnitsLength, "ScanBegin.units");
  m.start_time_ns = r.get<std::int64_t>("ScanBegin.start_time_ns");
  r.done();
}

void decode(const FrameView& f, msg::Stripe& m, std::span<msg::StripePoint> storage,
            const std::string& source) {
  PayloadReader r(f, source, msg::Type::Stripe);
  msg::StripeHeader& h = m.header;
  h.scan_id = r.get<std::uint64_t>("Stripe.scan_id");
  h.step_index = r.get<std::uint32_t>("Stripe.step_index");
  h.commanded_angle = r.get<double>("Stripe.commanded_angle");
  h.measured_position = r.get<double>("Stripe.measured_position");
  h.capture_time_ns = r.get<std::int64_t>("Stripe.capture_time_ns");
  h.frame_sequence = r.get<std::uint32_t>("Stripe.frame_sequence");
  h.flags = r.get<std::uint32_t>("Stripe.flags");
  const std::uint64_t at = r.offset();
  const std::uint32_t n = r.get<std::uint32_t>("Stripe.point_count");
  if (n > msg::kMaxStripePoints)
    throw r.fail_at(at, "Stripe.point_count " + std::to_string(n) + " exceeds maximum " +
                            std::to_string(msg::kMaxStripePoints));
  if (n > storage.size())
    throw r.fail_at(at, "Stripe.point_count " + std::to_string(n) + " exceeds the caller's storage of " +
                            std::to_string(storage.size()) + " points");
  if (static_cast<std::size_t>(n) * kStripePointSize > r.remaining())
    throw r.fail_at(at, "truncated payload: Stripe.point_count " + std::to_string(n) + " needs " +
                            std::to_string(static_cast<std::size_t>(n) * kStripePointSize) + " bytes, only " +
                            std::to_string(r.remaining()) + " left");
  const std::uint8_t* p = r.get_bytes(static_cast<std::size_t>(n) * kStripePointSize, "Stripe.points").data();
  msg::StripePoint* out = storage.data();
  for (std::uint32_t i = 0; i < n; ++i, p += kStripePointSize) {
    out[i].row = load_le<std::uint16_t>(p);
    out[i].col = load_le<float>(p + 2);
    out[i].peak = load_le<std::uint16_t>(p + 6);
    out[i].width = load_le<float>(p + 8);
  }
  m.points = storage.first(n);
  r.done();
}

void decode(const FrameView& f, msg::ScanEnd& m, const std::string& source) {
  PayloadReader r(f, source, msg::Type::ScanEnd);
  m.scan_id = r.get<std::uint64_t>("ScanEnd.scan_id");
  m.stripes_sent = r.get<std::uint32_t>("ScanEnd.stripes_sent");
  m.frames_captured = r.get<std::uint32_t>("ScanEnd.frames_captured");
  m.frames_dropped = r.get<std::uint32_t>("ScanEnd.frames_dropped");
  m.stripes_dropped = r.get<std::uint32_t>("ScanEnd.stripes_dropped");
  m.fault_count = r.get<std::uint32_t>("ScanEnd.fault_count");
  m.last_fault_code = r.get<std::uint32_t>("ScanEnd.last_fault_code");
  m.completed = r.get<std::uint8_t>("ScanEnd.completed");
  msg::LoopStats& s = m.loop;
  s.lateness_min_ns = r.get<std::int64_t>("ScanEnd.loop.lateness_min_ns");
  s.lateness_median_ns = r.get<std::int64_t>("ScanEnd.loop.lateness_median_ns");
  s.lateness_p99_ns = r.get<std::int64_t>("ScanEnd.loop.lateness_p99_ns");
  s.lateness_p999_ns = r.get<std::int64_t>("ScanEnd.loop.lateness_p999_ns");
  s.lateness_max_ns = r.get<std::int64_t>("ScanEnd.loop.lateness_max_ns");
  s.overruns = r.get<std::uint32_t>("ScanEnd.loop.overruns");
  s.extraction_mean_ns = r.get<std::int64_t>("ScanEnd.loop.extraction_mean_ns");
  s.extraction_max_ns = r.get<std::int64_t>("ScanEnd.loop.extraction_max_ns");
  r.done();
}

void decode(const FrameView& f, msg::Heartbeat& m, const std::string& source) {
  PayloadReader r(f, source, msg::Type::Heartbeat);
  m.time_ns = r.get<std::int64_t>("Heartbeat.time_ns");
  m.counter = r.get<std::uint64_t>("Heartbeat.counter");
  m.state = r.get<std::uint8_t>("Heartbeat.state");
  r.done();
}

void decode(const FrameView& f, msg::Fault& m, const std::string& source) {
  PayloadReader r(f, source, msg::Type::Fault);
  m.code = r.get<std::uint32_t>("Fault.code");
  r.get_string(m.text, msg::kMaxFaultText, "Fault.text");
  r.done();
}

DecodedMessage::DecodedMessage() : point_storage(msg::kMaxStripePoints) {
  scan_begin.scanner_model.reserve(msg::kMaxModelName);
  scan_begin.units.reserve(kMaxUnitsLength);
  fault.text.reserve(msg::kMaxFaultText);
}

void decode(const FrameView& f, DecodedMessage& out, const std::string& source) {
  out.type = f.header.type;
  out.sequence = f.header.sequence;
  out.offset = f.offset;
  switch (f.header.type) {
    case msg::Type::ScanBegin:
      decode(f, out.scan_begin, source);
      return;
    case msg::Type::Stripe:
      decode(f, out.stripe, out.point_storage, source);
      return;
    case msg::Type::ScanEnd:
      decode(f, out.scan_end, source);
      return;
    case msg::Type::Heartbeat:
      decode(f, out.heartbeat, source);
      return;
    case msg::Type::Fault:
      decode(f, out.fault, source);
      return;
  }
  throw error_at_offset(source, f.offset + 6, "unknown message type");
}

// ---- frame header and incremental decoder
// --------------------------------------------------------------------

FrameHeader parse_header(std::span<const std::uint8_t> b, std::size_t max_payload, const std::string& source,
                         std::uint64_t offset) {
  if (b.size() < kFrameHeaderSize)
    throw error_at_offset(source, offset,
                          "truncated frame header: " + std::to_string(b.size()) + " of " +
                              std::to_string(kFrameHeaderSize) + " bytes");
  for (std::size_t i = 0; i < kMagic.size(); ++i)
    if (b[i] != kMagic[i]) {
      char what[96];
      std::snprintf(what, sizeof what,
                    "bad frame magic %02x %02x %02x %02x (expected \"FSWF\"; byte %zu differs)", b[0], b[1],
                    b[2], b[3], i);
      throw error_at_offset(source, offset + i, what);
    }
  FrameHeader h;
  h.major = b[4];
  h.minor = b[5];
  if (h.major != kProtocolMajor)
    throw error_at_offset(source, offset + 4,
                          "unsupported protocol version " + std::to_string(h.major) + "." +
                              std::to_string(h.minor) + " (this reader speaks major version " +
                              std::to_string(kProtocolMajor) + ")");
  if (!is_known_type(b[6]))
    throw error_at_offset(source, offset + 6, "unknown message type " + std::to_string(b[6]));
  h.type = static_cast<msg::Type>(b[6]);
  h.payload_length = load_le<std::uint32_t>(b.data() + 8);
  if (h.payload_length > max_payload)
    throw error_at_offset(source, offset + 8,
                          "payload length " + std::to_string(h.payload_length) + " exceeds maximum " +
                              std::to_string(max_payload) + " (" + type_name(h.type) + " frame)");
  h.sequence = load_le<std::uint32_t>(b.data() + 12);
  return h;
}

FrameDecoder::FrameDecoder(std::string source, Limits limits, std::uint64_t base_offset)
    : source_(std::move(source)), limits_(limits), base_(base_offset) {
  if (limits_.max_payload > kMaxConfigurablePayload)
    throw Error(source_ + ": decoder payload limit " + std::to_string(limits_.max_payload) + " exceeds " +
                std::to_string(kMaxConfigurablePayload));
  buf_.resize(limits_.max_payload + kFrameOverhead);
  error_.reserve(256);
}

void FrameDecoder::reset(std::uint64_t base_offset) {
  start_ = end_ = 0;
  base_ = base_offset;
  frames_ = gaps_ = 0;
  last_seq_ = 0;
  have_seq_ = false;
  failed_ = false;
  error_.clear();
}

void FrameDecoder::compact() {
  if (start_ == 0) return;
  const std::size_t n = end_ - start_;
  if (n > 0) std::memmove(buf_.data(), buf_.data() + start_, n);
  base_ += start_;
  start_ = 0;
  end_ = n;
}

std::size_t FrameDecoder::feed(std::span<const std::uint8_t> bytes) {
  if (end_ == buf_.size())
    compact();
  else if (buf_.size() - end_ < bytes.size() && start_ > 0)
    compact();
  const std::size_t n = std::min(bytes.size(), buf_.size() - end_);
  if (n > 0) std::memcpy(buf_.data() + end_, bytes.data(), n);
  end_ += n;
  return n;
}

void FrameDecoder::fail(std::uint64_t at, const std::string& what) {
  failed_ = true;
  error_ = error_at_offset(source_, at, what).what();
  throw Error(error_);
}

bool FrameDecoder::next(FrameView& out) {
  if (failed_) throw Error(error_);
  const std::size_t avail = end_ - start_;
  if (avail < kFrameHeaderSize) {
    // Reject a bad magic as soon as its bytes are here (no waiting for a whole header on garbage).
    for (std::size_t i = 0; i < std::min(avail, kMagic.size()); ++i) {
      if (buf_[start_ + i] != kMagic[i]) {
        char what[80];
        std::snprintf(what, sizeof what, "bad frame magic: byte %zu is 0x%02x (expected \"FSWF\")", i,
                      buf_[start_ + i]);
        fail(offset() + i, what);
      }
    }
    return false;
  }
  const std::uint8_t* p = buf_.data() + start_;
  FrameHeader h;
  try {
    h = parse_header({p, kFrameHeaderSize}, limits_.max_payload, source_, offset());
  } catch (const Error& e) {
    failed_ = true;
    error_ = e.what();
    throw;
  }
  const std::size_t total = kFrameHeaderSize + h.payload_length + kFrameCrcSize;
  if (avail < total) return false;
  const std::uint32_t want = load_le<std::uint32_t>(p + kFrameHeaderSize + h.payload_length);
  const std::uint32_t got = crc32c({p, kFrameHeaderSize + h.payload_length});
  if (want != got) {
    char msg[96];
    std::snprintf(msg, sizeof msg,
                  "bad CRC-32C: frame says 0x%08x, computed 0x%08x (%s frame of %u payload bytes)", want, got,
                  type_name(h.type), h.payload_length);
    fail(offset() + kFrameHeaderSize + h.payload_length, msg);
  }
  out.header = h;
  out.payload = std::span<const std::uint8_t>(p + kFrameHeaderSize, h.payload_length);
  out.offset = offset();
  if (have_seq_ && h.sequence != static_cast<std::uint32_t>(last_seq_ + 1)) ++gaps_;
  last_seq_ = h.sequence;
  have_seq_ = true;
  ++frames_;
  start_ += total;
  return true;
}

void FrameDecoder::finish() {
  if (failed_) throw Error(error_);
  const std::size_t avail = end_ - start_;
  if (avail == 0) return;
  if (avail < kFrameHeaderSize)
    fail(offset(), "truncated frame: stream ends " + std::to_string(avail) + " bytes into a frame header");
  const FrameHeader h =
      parse_header({buf_.data() + start_, kFrameHeaderSize}, limits_.max_payload, source_, offset());
  const std::size_t total = kFrameHeaderSize + h.payload_length + kFrameCrcSize;
  fail(offset(), "truncated frame: " + std::string(type_name(h.type)) + " frame needs " +
                     std::to_string(total) + " bytes, stream ends after " + std::to_string(avail));
}

std::size_t FrameDecoder::resync() {
  failed_ = false;
  error_.clear();
  if (start_ == end_) return 0;
  std::size_t i = start_ + 1;
  for (; i < end_; ++i) {
    const std::size_t k = std::min<std::size_t>(kMagic.size(), end_ - i);
    if (std::equal(kMagic.begin(), kMagic.begin() + static_cast<std::ptrdiff_t>(k),
                   buf_.begin() + static_cast<std::ptrdiff_t>(i)))
      break;
  }
  const std::size_t skipped = i - start_;
  start_ = i;
  have_seq_ = false;  // sequence continuity restarts
  return skipped;
}

}  // namespace fs::wire
