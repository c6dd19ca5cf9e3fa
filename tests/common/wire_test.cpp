#include "common/wire.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <random>

#include "common/byte_io.hpp"
#include "common/crc32c.hpp"
#include "support/error_of.hpp"
#include "wire_samples.hpp"

namespace {

using namespace fs;
using ::testing::HasSubstr;

// A raw frame with arbitrary header fields and a correct CRC (to build frames the encoder never writes).
std::vector<std::uint8_t> raw_frame(std::uint8_t type, std::span<const std::uint8_t> payload,
                                    std::uint8_t major = 1, std::uint8_t minor = 0, std::uint32_t seq = 0) {
  std::vector<std::uint8_t> f(wire::kFrameHeaderSize + payload.size() + 4);
  std::memcpy(f.data(), "FSWF", 4);
  f[4] = major;
  f[5] = minor;
  f[6] = type;
  store_le<std::uint32_t>(f.data() + 8, static_cast<std::uint32_t>(payload.size()));
  store_le<std::uint32_t>(f.data() + 12, seq);
  if (!payload.empty()) std::memcpy(f.data() + 16, payload.data(), payload.size());
  store_le<std::uint32_t>(f.data() + 16 + payload.size(), crc32c({f.data(), 16 + payload.size()}));
  return f;
}

template <class M>
std::vector<std::uint8_t> encoded(const M& m, std::uint32_t seq = 0) {
  std::vector<std::uint8_t> out(wire::frame_size(m));
  EXPECT_EQ(wire::encode(out, seq, m), out.size());
  return out;
}

// Feeds all bytes in one piece and pops exactly one frame.
wire::FrameView decode_one(wire::FrameDecoder& dec, std::span<const std::uint8_t> bytes) {
  EXPECT_EQ(dec.feed(bytes), bytes.size());
  wire::FrameView f;
  EXPECT_TRUE(dec.next(f));
  return f;
}

using fs::test::error_of;

std::string decode_error(std::span<const std::uint8_t> bytes, bool finish = false) {
  return error_of([&] {
    wire::FrameDecoder dec("s.bin");
    dec.feed(bytes);
    wire::FrameView f;
    while (dec.next(f)) {
      wire::DecodedMessage m;
      wire::decode(f, m, "s.bin");
    }
    if (finish) dec.finish();
  });
}

TEST(Wire, ScanBeginRoundTrip) {
  const auto m = test::sample_scan_begin();
  const auto bytes = encoded(m, 5);
  EXPECT_EQ(bytes.size(), wire::kScanBeginFixedSize + m.scanner_model.size() + m.units.size() + 20);
  wire::FrameDecoder dec;
  const auto f = decode_one(dec, bytes);
  EXPECT_EQ(f.header.type, msg::Type::ScanBegin);
  EXPECT_EQ(f.header.sequence, 5u);
  EXPECT_EQ(f.offset, 0u);
  msg::ScanBegin d;
  wire::decode(f, d);
  EXPECT_EQ(d.scan_id, m.scan_id);
  EXPECT_EQ(d.scanner_model, m.scanner_model);
  EXPECT_EQ(d.pixel_bits, 16);
  EXPECT_EQ(d.units, "mm");
  EXPECT_EQ(d.start_time_ns, m.start_time_ns);
  const auto &a = d.calibration, &b = m.calibration;
  EXPECT_EQ(a.camera.width, b.camera.width);
  EXPECT_EQ(a.camera.height, b.camera.height);
  EXPECT_EQ(a.camera.fx, b.camera.fx);
  EXPECT_EQ(a.camera.fy, b.camera.fy);
  EXPECT_EQ(a.camera.cx, b.camera.cx);
  EXPECT_EQ(a.camera.cy, b.camera.cy);
  EXPECT_EQ(a.camera.k1, b.camera.k1);
  EXPECT_EQ(a.camera.k2, b.camera.k2);
  EXPECT_EQ(a.camera.k3, b.camera.k3);
  EXPECT_EQ(a.camera.p1, b.camera.p1);
  EXPECT_EQ(a.camera.p2, b.camera.p2);
  EXPECT_EQ(a.camera.R_world_cam, b.camera.R_world_cam);
  EXPECT_EQ(a.camera.t_world_cam, b.camera.t_world_cam);
  EXPECT_EQ(a.laser.axis_point, b.laser.axis_point);
  EXPECT_EQ(a.laser.axis_dir, b.laser.axis_dir);
  EXPECT_EQ(a.laser.normal_at_zero, b.laser.normal_at_zero);
  EXPECT_EQ(a.laser.optical_gain, b.laser.optical_gain);
  EXPECT_EQ(a.laser.mirror_angle_at_step0, b.laser.mirror_angle_at_step0);
  EXPECT_EQ(a.laser.rad_per_step, b.laser.rad_per_step);
  EXPECT_EQ(a.first_step, -17);
  EXPECT_EQ(a.step_count, 321u);
  EXPECT_EQ(a.table.n, b.table.n);
  EXPECT_EQ(a.table.d, b.table.d);
}

TEST(Wire, StripeRoundTripIntoCallerStorage) {
  auto pts = test::sample_points(1000);
  const msg::Stripe m{test::sample_stripe_header(17), pts};
  const auto bytes = encoded(m, 9);
  EXPECT_EQ(bytes.size(), 48 + 12 * 1000 + 20u);
  wire::FrameDecoder dec;
  const auto f = decode_one(dec, bytes);
  std::vector<msg::StripePoint> storage(1000);
  msg::Stripe d;
  wire::decode(f, d, storage);
  EXPECT_EQ(d.points.data(), storage.data());
  ASSERT_EQ(d.points.size(), 1000u);
  EXPECT_EQ(d.header.scan_id, 42u);
  EXPECT_EQ(d.header.step_index, 17u);
  EXPECT_EQ(d.header.commanded_angle, m.header.commanded_angle);
  EXPECT_EQ(d.header.measured_position, m.header.measured_position);
  EXPECT_EQ(d.header.capture_time_ns, m.header.capture_time_ns);
  EXPECT_EQ(d.header.frame_sequence, m.header.frame_sequence);
  EXPECT_EQ(d.header.flags, 3u);
  for (std::size_t i = 0; i < 1000; ++i) {
    EXPECT_EQ(d.points[i].row, pts[i].row);
    EXPECT_EQ(d.points[i].col, pts[i].col);
    EXPECT_EQ(d.points[i].peak, pts[i].peak);
    EXPECT_EQ(d.points[i].width, pts[i].width);
  }
}

TEST(Wire, EmptyAndMaximalStripes) {
  for (std::size_t n : {std::size_t{0}, std::size_t{msg::kMaxStripePoints}}) {
    auto pts = test::sample_points(n);
    const auto bytes = encoded(msg::Stripe{test::sample_stripe_header(1), pts});
    EXPECT_LE(bytes.size(), wire::kMaxFrameSize);
    wire::FrameDecoder dec;
    wire::DecodedMessage d;
    wire::decode(decode_one(dec, bytes), d);
    EXPECT_EQ(d.type, msg::Type::Stripe);
    EXPECT_EQ(d.stripe.points.size(), n);
  }
}

TEST(Wire, ScanEndHeartbeatFaultRoundTrip) {
  wire::VectorSink sink;
  wire::FrameWriter w(sink, 100);
  w.send(test::sample_scan_end());
  w.send(test::sample_heartbeat());
  w.send(test::sample_fault());
  EXPECT_EQ(w.next_sequence(), 103u);
  wire::FrameDecoder dec;
  ASSERT_EQ(dec.feed(sink.data), sink.data.size());
  wire::FrameView f;
  wire::DecodedMessage d;

  ASSERT_TRUE(dec.next(f));
  wire::decode(f, d);
  EXPECT_EQ(d.type, msg::Type::ScanEnd);
  EXPECT_EQ(d.sequence, 100u);
  const auto e = test::sample_scan_end();
  EXPECT_EQ(d.scan_end.scan_id, e.scan_id);
  EXPECT_EQ(d.scan_end.stripes_sent, e.stripes_sent);
  EXPECT_EQ(d.scan_end.frames_captured, e.frames_captured);
  EXPECT_EQ(d.scan_end.frames_dropped, e.frames_dropped);
  EXPECT_EQ(d.scan_end.stripes_dropped, e.stripes_dropped);
  EXPECT_EQ(d.scan_end.fault_count, e.fault_count);
  EXPECT_EQ(d.scan_end.last_fault_code, e.last_fault_code);
  EXPECT_EQ(d.scan_end.completed, 1);
  EXPECT_EQ(d.scan_end.loop.lateness_min_ns, -5);
  EXPECT_EQ(d.scan_end.loop.lateness_median_ns, 1200);
  EXPECT_EQ(d.scan_end.loop.lateness_p99_ns, 8000);
  EXPECT_EQ(d.scan_end.loop.lateness_p999_ns, 15000);
  EXPECT_EQ(d.scan_end.loop.lateness_max_ns, 22000);
  EXPECT_EQ(d.scan_end.loop.overruns, 4u);
  EXPECT_EQ(d.scan_end.loop.extraction_mean_ns, 350000);
  EXPECT_EQ(d.scan_end.loop.extraction_max_ns, 900000);

  ASSERT_TRUE(dec.next(f));
  wire::decode(f, d);
  EXPECT_EQ(d.type, msg::Type::Heartbeat);
  EXPECT_EQ(d.heartbeat.time_ns, 987654321);
  EXPECT_EQ(d.heartbeat.counter, 77u);
  EXPECT_EQ(d.heartbeat.state, 3);

  ASSERT_TRUE(dec.next(f));
  wire::decode(f, d);
  EXPECT_EQ(d.type, msg::Type::Fault);
  EXPECT_EQ(d.fault.code, 17u);
  EXPECT_EQ(d.fault.text, "galvo following error 12 steps");
  EXPECT_FALSE(dec.next(f));
  EXPECT_EQ(dec.frames(), 3u);
  EXPECT_EQ(dec.sequence_gaps(), 0u);
  dec.finish();
}

TEST(Wire, GoldenBytesAreLittleEndianFieldByField) {
  const auto bytes = encoded(msg::Heartbeat{0x0102030405060708ll, 0x1112131415161718ull, 0x21}, 0xA0B0C0D0u);
  const std::vector<std::uint8_t> expect_head = {'F',  'S',  'W',  'F',  1,    0,    4,    0,    17,  0, 0, 0,
                                                 0xD0, 0xC0, 0xB0, 0xA0, 8,    7,    6,    5,    4,   3, 2, 1,
                                                 0x18, 0x17, 0x16, 0x15, 0x14, 0x13, 0x12, 0x11, 0x21};
  ASSERT_EQ(bytes.size(), expect_head.size() + 4);
  EXPECT_TRUE(std::equal(expect_head.begin(), expect_head.end(), bytes.begin()));
  EXPECT_EQ(load_le<std::uint32_t>(bytes.data() + 33), crc32c({bytes.data(), 33}));
}

TEST(Wire, ArbitraryChunkingYieldsTheSameFrames) {
  wire::VectorSink sink;
  wire::FrameWriter w(sink);
  w.send(test::sample_scan_begin());
  std::vector<std::vector<msg::StripePoint>> all;
  for (std::uint32_t k = 0; k < 20; ++k) {
    all.push_back(test::sample_points(k * 97 % 1500));
    w.send(msg::Stripe{test::sample_stripe_header(k), all.back()});
    if (k % 7 == 0) w.send(test::sample_heartbeat());
  }
  w.send(test::sample_scan_end());
  std::mt19937 rng(3);
  for (int trial = 0; trial < 20; ++trial) {
    wire::FrameDecoder dec("chunked");
    wire::DecodedMessage d;
    std::span<const std::uint8_t> in(sink.data);
    std::size_t stripes = 0, total = 0;
    while (!in.empty()) {
      const std::size_t chunk = std::min<std::size_t>(in.size(), trial == 0 ? 1 : 1 + rng() % 40000);
      auto piece = in.first(chunk);
      in = in.subspan(chunk);
      while (!piece.empty()) {
        piece = piece.subspan(dec.feed(piece));
        wire::FrameView f;
        while (dec.next(f)) {
          wire::decode(f, d);
          ++total;
          if (d.type == msg::Type::Stripe) {
            const auto& ref = all[stripes++];
            ASSERT_EQ(d.stripe.points.size(), ref.size());
            if (!ref.empty()) {
              EXPECT_EQ(d.stripe.points.back().col, ref.back().col);
            }
          }
        }
      }
    }
    dec.finish();
    EXPECT_EQ(stripes, 20u);
    EXPECT_EQ(total, 20u + 3u + 2u);
  }
}

// ---- malformed input
// ---------------------------------------------------------------------------------------

TEST(WireErrors, BadMagicNamesOffset) {
  auto a = encoded(test::sample_heartbeat(), 0);
  auto b = encoded(test::sample_heartbeat(), 1);
  b[2] = 'X';
  a.insert(a.end(), b.begin(), b.end());
  const auto err = decode_error(a);
  EXPECT_THAT(err, HasSubstr("s.bin: at byte 39"));
  EXPECT_THAT(err, HasSubstr("bad frame magic"));
}

TEST(WireErrors, BadMagicDetectedBeforeWholeHeader) {
  const std::vector<std::uint8_t> garbage = {'F', 'S', 'Q'};
  EXPECT_THAT(decode_error(garbage), HasSubstr("at byte 2: bad frame magic"));
}

TEST(WireErrors, BadCrcNamesOffset) {
  auto a = encoded(test::sample_fault());
  a[20] ^= 0x40;  // a payload bit
  const auto err = decode_error(a);
  EXPECT_THAT(err, HasSubstr("bad CRC-32C"));
  EXPECT_THAT(err, HasSubstr("at byte " + std::to_string(a.size() - 4)));
  auto b = encoded(test::sample_fault());
  b.back() ^= 1;  // the CRC itself
  EXPECT_THAT(decode_error(b), HasSubstr("bad CRC-32C"));
}

TEST(WireErrors, TruncatedFrameAtEndOfStream) {
  auto pts = test::sample_points(10);
  const auto full = encoded(msg::Stripe{test::sample_stripe_header(0), pts});
  for (std::size_t cut :
       {std::size_t{1}, std::size_t{10}, std::size_t{16}, std::size_t{100}, full.size() - 1}) {
    std::vector<std::uint8_t> part(full.begin(), full.begin() + static_cast<std::ptrdiff_t>(cut));
    const auto err = decode_error(part, /*finish=*/true);
    EXPECT_THAT(err, HasSubstr("s.bin: at byte 0: truncated frame")) << cut;
  }
}

TEST(WireErrors, TruncatedPayloadInsideAValidFrame) {
  // A Heartbeat whose payload is 3 bytes short (frame CRC is correct): the field is named.
  const auto good = encoded(test::sample_heartbeat());
  std::vector<std::uint8_t> payload(good.begin() + 16, good.end() - 4 - 3);
  const auto err = decode_error(raw_frame(4, payload));
  EXPECT_THAT(err, HasSubstr("truncated payload: field Heartbeat.counter"));
  EXPECT_THAT(err, HasSubstr("at byte 24"));
}

TEST(WireErrors, StripePointCountBeyondPayload) {
  auto pts = test::sample_points(10);
  const auto good = encoded(msg::Stripe{test::sample_stripe_header(0), pts});
  std::vector<std::uint8_t> payload(good.begin() + 16, good.end() - 4);
  store_le<std::uint32_t>(payload.data() + 44, 11);
  const auto err = decode_error(raw_frame(2, payload));
  EXPECT_THAT(err, HasSubstr("at byte 60: truncated payload: Stripe.point_count 11"));
  store_le<std::uint32_t>(payload.data() + 44, msg::kMaxStripePoints + 1);
  EXPECT_THAT(decode_error(raw_frame(2, payload)), HasSubstr("exceeds maximum 8192"));
}

TEST(WireErrors, StripePointCountBeyondCallerStorage) {
  auto pts = test::sample_points(100);
  const auto bytes = encoded(msg::Stripe{test::sample_stripe_header(0), pts});
  wire::FrameDecoder dec;
  const auto f = decode_one(dec, bytes);
  std::vector<msg::StripePoint> small(99);
  msg::Stripe s;
  EXPECT_THAT(error_of([&] { wire::decode(f, s, small); }), HasSubstr("exceeds the caller's storage of 99"));
}

TEST(WireErrors, OversizeLengthRejectedFromHeader) {
  std::vector<std::uint8_t> head = {'F', 'S', 'W', 'F', 1, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0};
  store_le<std::uint32_t>(head.data() + 8, 0xFFFFFFF0u);
  const auto err = decode_error(head);  // the decoder does not wait for 4 GB
  EXPECT_THAT(err, HasSubstr("at byte 8: payload length 4294967280 exceeds maximum"));
  // A configured smaller limit.
  auto pts = test::sample_points(100);
  const auto stripe = encoded(msg::Stripe{test::sample_stripe_header(0), pts});
  EXPECT_THROW(wire::FrameDecoder("huge", wire::DecoderLimits{std::size_t{1} << 40}), fs::Error);
  wire::FrameDecoder dec("lim", wire::DecoderLimits{1000});
  dec.feed(stripe);
  wire::FrameView f;
  EXPECT_THAT(error_of([&] { dec.next(f); }), HasSubstr("exceeds maximum 1000"));
}

TEST(WireErrors, UnknownType) {
  const std::vector<std::uint8_t> payload(8, 0);
  for (std::uint8_t t : {0, 6, 255})
    EXPECT_THAT(decode_error(raw_frame(t, payload)), HasSubstr("at byte 6: unknown message type"));
}

TEST(WireErrors, UnknownMajorVersion) {
  const auto good = encoded(test::sample_heartbeat());
  std::vector<std::uint8_t> payload(good.begin() + 16, good.end() - 4);
  const auto err = decode_error(raw_frame(4, payload, 2, 0));
  EXPECT_THAT(err, HasSubstr("at byte 4: unsupported protocol version 2.0"));
  EXPECT_THAT(decode_error(raw_frame(4, payload, 0, 9)), HasSubstr("unsupported protocol version 0.9"));
}

TEST(WireErrors, NewerMinorVersionIsAcceptedWithExtraFields) {
  const auto good = encoded(test::sample_heartbeat());
  std::vector<std::uint8_t> payload(good.begin() + 16, good.end() - 4);
  payload.insert(payload.end(), {1, 2, 3, 4, 5});  // fields added by protocol 1.3
  wire::FrameDecoder dec;
  const auto frame = raw_frame(4, payload, 1, 3);
  const auto f = decode_one(dec, frame);
  EXPECT_EQ(f.header.minor, 3);
  msg::Heartbeat h;
  wire::decode(f, h);
  EXPECT_EQ(h.counter, 77u);
  // The same trailing bytes in a 1.0 frame are an error.
  EXPECT_THAT(decode_error(raw_frame(4, payload, 1, 0)), HasSubstr("5 unexpected trailing bytes"));
}

TEST(WireErrors, BadFieldValues) {
  auto m = test::sample_scan_begin();
  m.pixel_bits = 12;
  EXPECT_THAT(decode_error(encoded(m)), HasSubstr("pixel_bits is 12"));
  // Calibration values the host could not use.
  m = test::sample_scan_begin();
  m.calibration.camera.fx = std::numeric_limits<double>::quiet_NaN();
  // scan_id 8 + model (2 + 17) + width 4 + height 4 = byte 35 of the payload, 51 of the frame.
  EXPECT_THAT(decode_error(encoded(m)), HasSubstr("at byte 51: ScanBegin.camera.fx is not finite"));
  m = test::sample_scan_begin();
  m.calibration.camera.fy = -3;
  EXPECT_THAT(decode_error(encoded(m)), HasSubstr("ScanBegin.camera.fy must be > 0"));
  m = test::sample_scan_begin();
  m.calibration.camera.height = 0;
  EXPECT_THAT(decode_error(encoded(m)),
              HasSubstr("at byte 47: ScanBegin.camera.height is 0, expected 1..65536"));
  m = test::sample_scan_begin();
  m.calibration.laser.axis_dir.y() = std::numeric_limits<double>::infinity();
  EXPECT_THAT(decode_error(encoded(m)), HasSubstr("ScanBegin.laser.axis_dir is not finite (inf)"));
  m = test::sample_scan_begin();
  m.calibration.step_count = 0;
  EXPECT_THAT(decode_error(encoded(m)), HasSubstr("ScanBegin.step_count is 0"));
  // A string length beyond its maximum.
  auto good = encoded(test::sample_fault());
  std::vector<std::uint8_t> payload(good.begin() + 16, good.end() - 4);
  store_le<std::uint16_t>(payload.data() + 4, 300);
  EXPECT_THAT(decode_error(raw_frame(5, payload)),
              HasSubstr("at byte 20: Fault.text: length 300 exceeds maximum 256"));
}

TEST(WireErrors, DecodeAsWrongTypeIsAnError) {
  wire::FrameDecoder dec;
  const auto bytes = encoded(test::sample_heartbeat());
  const auto f = decode_one(dec, bytes);
  msg::Fault fault;
  EXPECT_THAT(error_of([&] { wire::decode(f, fault); }),
              HasSubstr("frame type is Heartbeat, expected Fault"));
}

TEST(WireErrors, EncodeChecksLimits) {
  std::vector<std::uint8_t> small(10);
  EXPECT_THAT(error_of([&] { wire::encode(small, 0, test::sample_heartbeat()); }), HasSubstr("too small"));
  msg::Fault f{1, std::string(msg::kMaxFaultText + 1, 'x')};
  std::vector<std::uint8_t> big(4096);
  EXPECT_THAT(error_of([&] { wire::encode(big, 0, f); }), HasSubstr("Fault.text is 257 bytes, maximum 256"));
  auto pts = test::sample_points(msg::kMaxStripePoints + 1);
  std::vector<std::uint8_t> huge(wire::kMaxFrameSize + 100);
  EXPECT_THAT(error_of([&] { wire::encode(huge, 0, msg::Stripe{{}, pts}); }), HasSubstr("maximum 8192"));
}

TEST(WireErrors, DecoderStaysFailedUntilResync) {
  auto a = encoded(test::sample_heartbeat(), 0);
  auto bad = encoded(test::sample_heartbeat(), 1);
  bad[18] ^= 0xFF;
  auto c = encoded(test::sample_heartbeat(), 2);
  std::vector<std::uint8_t> stream = a;
  stream.insert(stream.end(), {0x00, 0x13, 'F', 'S'});  // line noise including a false magic start
  stream.insert(stream.end(), bad.begin(), bad.end());
  stream.insert(stream.end(), c.begin(), c.end());
  wire::FrameDecoder dec("link");
  dec.feed(stream);
  wire::FrameView f;
  ASSERT_TRUE(dec.next(f));
  EXPECT_THAT(error_of([&] { dec.next(f); }), HasSubstr("link: at byte 37: bad frame magic"));
  EXPECT_TRUE(dec.failed());
  EXPECT_THAT(error_of([&] { dec.next(f); }), HasSubstr("at byte 37"));  // sticky
  std::vector<std::uint32_t> good_seqs;
  for (int guard = 0; guard < 100; ++guard) {
    try {
      while (dec.next(f)) good_seqs.push_back(f.header.sequence);
      break;
    } catch (const fs::Error&) {
      EXPECT_GT(dec.resync(), 0u);
    }
  }
  EXPECT_EQ(good_seqs, std::vector<std::uint32_t>{2});
  EXPECT_EQ(dec.sequence_gaps(), 0u);  // continuity restarts after resync
}

TEST(Wire, SequenceGapsAreCounted) {
  wire::VectorSink sink;
  for (std::uint32_t s : {1u, 2u, 5u, 6u, 9u}) {
    const auto b = encoded(test::sample_heartbeat(), s);
    sink.write(b);
  }
  wire::FrameDecoder dec;
  dec.feed(sink.data);
  wire::FrameView f;
  while (dec.next(f)) {
  }
  EXPECT_EQ(dec.frames(), 5u);
  EXPECT_EQ(dec.sequence_gaps(), 2u);
}

TEST(Wire, TeeSinkWritesBoth) {
  wire::VectorSink a, b;
  wire::TeeSink tee(a, b);
  wire::FrameWriter w(tee);
  w.send(test::sample_fault());
  EXPECT_EQ(a.data, b.data);
  EXPECT_EQ(a.data.size(), wire::frame_size(test::sample_fault()));
}

TEST(Wire, BaseOffsetShiftsErrorOffsets) {
  auto a = encoded(test::sample_heartbeat());
  a[0] = 'X';
  wire::FrameDecoder dec("file.fscan", {}, 16);
  dec.feed(a);
  wire::FrameView f;
  EXPECT_THAT(error_of([&] { dec.next(f); }), HasSubstr("file.fscan: at byte 16: bad frame magic"));
}

}  // namespace
