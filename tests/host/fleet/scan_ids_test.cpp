// Scan ids (host/fleet/ids.hpp): the digest tells apart two scans whose frames have the same sizes, which a
// CRC-32C over the image cannot (every frame ends with its own CRC-32C: the CRC residue).
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "common/crc32c.hpp"
#include "host/fleet/ids.hpp"
#include "host/io/scan.hpp"
#include "host/io/scan_bytes.hpp"
#include "host/io/scan_writer.hpp"

namespace {

using namespace fs;
using namespace fs::host;

// A .fscan image of one scan: `steps` stripes of `points` points whose columns depend on `seed`.
std::vector<std::uint8_t> image_of(std::uint64_t scan_id, float seed, int steps = 8, int points = 16) {
  msg::ScanBegin b;
  b.calibration = ScannerCalibration::bench_default();
  b.scan_id = scan_id;
  b.start_time_ns = 1'000'000'000;
  b.calibration.step_count = static_cast<std::uint32_t>(steps);
  Scan scan;
  scan.start(b);
  std::vector<msg::StripePoint> pts(static_cast<std::size_t>(points));
  for (int k = 0; k < steps; ++k) {
    for (int i = 0; i < points; ++i)
      pts[static_cast<std::size_t>(i)] = {static_cast<std::uint16_t>(i),
                                          seed + 0.25f * static_cast<float>(k + i), 200, 2.0f};
    msg::Stripe s;
    s.header.scan_id = scan_id;
    s.header.step_index = static_cast<std::uint32_t>(k);
    s.points = pts;
    scan.add_stripe(s);
  }
  return encode_scan_bytes(scan);
}

TEST(ScanIds, DigestSeparatesScansWithEqualFrameSizes) {
  const auto a = image_of(1, 100.0f), b = image_of(1, 300.0f);
  ASSERT_EQ(a.size(), b.size());
  ASSERT_NE(a, b);
  // The pitfall this digest avoids: CRC-32C over CRC-32C-terminated frames depends on the frame sizes only.
  EXPECT_EQ(crc32c(a), crc32c(b));
  EXPECT_NE(fleet::image_digest(a), fleet::image_digest(b));
  EXPECT_NE(fleet::scan_message_id("cell-1", 1, 1'000'000'000, a),
            fleet::scan_message_id("cell-1", 1, 1'000'000'000, b));
  // The same bytes give the same id (a re-sent scan is stored once).
  EXPECT_EQ(fleet::scan_message_id("cell-1", 1, 1'000'000'000, a),
            fleet::scan_message_id("cell-1", 1, 1'000'000'000, image_of(1, 100.0f)));
}

TEST(ScanIds, Format) {
  const std::vector<std::uint8_t> bytes = {'a', 'b', 'c'};
  EXPECT_EQ(fleet::image_digest(bytes), 0x352441c2u);  // CRC-32 (ISO-HDLC) of "abc"
  EXPECT_EQ(fleet::scan_message_id("cell-7", 42, 123, bytes), "cell-7-42-123-352441c2");
}

TEST(ScanIds, StreamedScanIdsAndSubjects) {
  // Fixed at ScanBegin (no image yet): the gateway's nonce tells two scans with equal ids and start times
  // apart. Every id is one subject token (no '.', '*', '>', spaces).
  const std::string id = fleet::streamed_scan_id("cell-7", 42, 123, 0xab);
  EXPECT_EQ(id, "cell-7-42-123-s00000000000000ab");
  EXPECT_NE(id, fleet::streamed_scan_id("cell-7", 42, 123, 0xac));
  EXPECT_EQ(id.find_first_of(".*> "), std::string::npos);
  EXPECT_EQ(fleet::parts_subject("cell-7", id), "facetscan.parts.cell-7." + id);
  EXPECT_EQ(fleet::part_message_id(id, 12), id + "-p12");
  // A streamed id never equals a whole scan's id (their last fields differ in form).
  EXPECT_NE(id.substr(id.rfind('-') + 1).size(), 8u);
}

}  // namespace
