#include "common/scan_file.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

#include "common/byte_io.hpp"
#include "support/error_of.hpp"
#include "tmp_dir.hpp"
#include "wire_samples.hpp"

namespace {

using namespace fs;
using ::testing::HasSubstr;

std::vector<std::uint8_t> read_all(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Writes a scan: ScanBegin, `stripes` stripes of `points` points, a Fault, ScanEnd.
void write_scan(wire::FrameSink& sink, std::uint32_t stripes, std::size_t points) {
  wire::FrameWriter w(sink);
  w.send(test::sample_scan_begin());
  auto pts = test::sample_points(points);
  for (std::uint32_t k = 0; k < stripes; ++k) {
    pts[0].row = static_cast<std::uint16_t>(k);
    w.send(msg::Stripe{test::sample_stripe_header(k), pts});
  }
  w.send(test::sample_fault());
  w.send(test::sample_scan_end());
}

struct Counts {
  int begin = 0, stripes = 0, end = 0, fault = 0;
};
Counts read_scan(ScanFileReader& r) {
  Counts c;
  wire::DecodedMessage m;
  while (r.next(m)) {
    switch (m.type) {
      case msg::Type::ScanBegin:
        ++c.begin;
        EXPECT_EQ(m.scan_begin.scanner_model, "facetscan-bench-1");
        EXPECT_EQ(m.scan_begin.calibration.step_count, 321u);
        break;
      case msg::Type::Stripe:
        EXPECT_EQ(m.stripe.header.step_index, static_cast<std::uint32_t>(c.stripes));
        EXPECT_EQ(m.stripe.points[0].row, c.stripes);
        ++c.stripes;
        break;
      case msg::Type::ScanEnd:
        ++c.end;
        break;
      case msg::Type::Fault:
        ++c.fault;
        break;
      case msg::Type::Heartbeat:
        break;
    }
  }
  return c;
}

using fs::test::error_of;

std::string read_error(const std::vector<std::uint8_t>& image) {
  return error_of([&] {
    ScanFileReader r(image, "x.fscan");
    read_scan(r);
  });
}

class ScanFile : public ::testing::Test {
 protected:
  std::filesystem::path tmp = test::make_tmp_dir("scan_file");
  void TearDown() override { std::filesystem::remove_all(tmp); }
};

TEST_F(ScanFile, WriteAndReadBack) {
  const auto path = tmp / "a.fscan";
  {
    ScanFileWriter w(path);
    write_scan(w, 300, 700);  // > 64 KiB read chunks, frames straddle chunk boundaries
    w.close();
    EXPECT_EQ(w.bytes_written(), std::filesystem::file_size(path));
  }
  ScanFileReader r(path);
  EXPECT_EQ(r.format_major(), 1);
  const Counts c = read_scan(r);
  EXPECT_EQ(c.begin, 1);
  EXPECT_EQ(c.stripes, 300);
  EXPECT_EQ(c.fault, 1);
  EXPECT_EQ(c.end, 1);
  EXPECT_EQ(r.frames_read(), 303u);
}

TEST_F(ScanFile, RecordingRawStreamBytesIsTheSameFile) {
  // Live stream bytes (as received from TCP, in odd chunks) written into a ScanFileWriter give the same file
  // as encoding straight into it.
  wire::VectorSink stream;
  write_scan(stream, 20, 50);
  const auto recorded = tmp / "recorded.fscan";
  {
    ScanFileWriter w(recorded);
    std::span<const std::uint8_t> in(stream.data);
    while (!in.empty()) {
      const std::size_t n = std::min<std::size_t>(in.size(), 777);
      w.write(in.first(n));
      in = in.subspan(n);
    }
  }
  const auto direct = tmp / "direct.fscan";
  {
    ScanFileWriter w(direct);
    write_scan(w, 20, 50);
  }
  EXPECT_EQ(read_all(recorded), read_all(direct));
  ScanFileReader r(recorded);
  EXPECT_EQ(read_scan(r).stripes, 20);
}

TEST_F(ScanFile, InMemoryImageMatchesFile) {
  const auto path = tmp / "m.fscan";
  {
    ScanFileWriter w(path);
    write_scan(w, 5, 10);
  }
  const auto image = read_all(path);
  ScanFileReader r(image, "mem");
  EXPECT_EQ(read_scan(r).stripes, 5);
}

TEST_F(ScanFile, MissingFile) {
  EXPECT_THAT(error_of([&] { ScanFileReader r(tmp / "nope.fscan"); }), HasSubstr("nope.fscan: cannot open"));
  EXPECT_THAT(error_of([&] { ScanFileWriter w(tmp / "no" / "dir" / "x.fscan"); }),
              HasSubstr("cannot create"));
}

TEST_F(ScanFile, EmptyScanIsValid) {
  const auto path = tmp / "empty.fscan";
  { ScanFileWriter w(path); }
  EXPECT_EQ(std::filesystem::file_size(path), kScanFileHeaderSize);
  ScanFileReader r(path);
  wire::DecodedMessage m;
  EXPECT_FALSE(r.next(m));
}

std::vector<std::uint8_t> sample_image(std::uint32_t stripes = 3) {
  wire::VectorSink s;
  std::array<std::uint8_t, kScanFileHeaderSize> h{};
  encode_scan_file_header(h);
  s.write(h);
  write_scan(s, stripes, 10);
  return s.data;
}

TEST(ScanFileErrors, BadFileMagic) {
  auto img = sample_image();
  img[3] = 'X';
  EXPECT_THAT(read_error(img), HasSubstr("x.fscan: at byte 3: not a .fscan file"));
  EXPECT_THAT(read_error({'h', 'e', 'l', 'l', 'o'}), HasSubstr("truncated .fscan file header: 5 of 16"));
  EXPECT_THAT(read_error({}), HasSubstr("truncated .fscan file header: 0 of 16"));
}

TEST(ScanFileErrors, UnknownFormatVersion) {
  auto img = sample_image();
  store_le<std::uint16_t>(img.data() + 8, 2);
  EXPECT_THAT(read_error(img), HasSubstr("x.fscan: at byte 8: unsupported .fscan format version 2.0"));
}

TEST(ScanFileErrors, NewerMinorWithLargerHeaderIsAccepted) {
  auto img = sample_image();
  store_le<std::uint16_t>(img.data() + 10, 4);
  store_le<std::uint32_t>(img.data() + 12, 24);
  img.insert(img.begin() + 16, 8, 0xAB);  // header fields of format 1.4
  ScanFileReader r(img, "new.fscan");
  EXPECT_EQ(r.format_minor(), 4);
  EXPECT_EQ(read_scan(r).stripes, 3);
  store_le<std::uint32_t>(img.data() + 12, 8);
  EXPECT_THAT(read_error(img), HasSubstr("at byte 12: bad .fscan header size 8"));
}

TEST(ScanFileErrors, TruncationAnywhereIsReportedWithOffset) {
  const auto img = sample_image(2);
  // Every cut inside the frame stream that is not at a frame boundary is a truncation.
  std::vector<std::size_t> boundaries;
  {
    ScanFileReader r(img, "b");
    wire::FrameView f;
    while (r.next_frame(f)) boundaries.push_back(f.offset);
    boundaries.push_back(img.size());
  }
  int truncations = 0;
  for (std::size_t cut = kScanFileHeaderSize; cut < img.size(); cut += 7) {
    std::vector<std::uint8_t> part(img.begin(), img.begin() + static_cast<std::ptrdiff_t>(cut));
    const auto err = read_error(part);
    const bool at_boundary = std::find(boundaries.begin(), boundaries.end(), cut) != boundaries.end();
    if (at_boundary) {
      EXPECT_EQ(err, "<no error>") << cut;
    } else {
      // The offset named is the start of the cut frame.
      const auto frame_start = *(std::upper_bound(boundaries.begin(), boundaries.end(), cut) - 1);
      EXPECT_THAT(err, HasSubstr("x.fscan: at byte " + std::to_string(frame_start) + ": truncated frame"))
          << cut;
      ++truncations;
    }
  }
  EXPECT_GT(truncations, 10);
}

TEST(ScanFileErrors, BadCrcNamesFileOffset) {
  auto img = sample_image();
  // Flip a bit in the second frame (the first Stripe) payload.
  ScanFileReader r(img, "b");
  wire::FrameView f;
  ASSERT_TRUE(r.next_frame(f));
  ASSERT_TRUE(r.next_frame(f));
  const std::size_t crc_at = f.offset + wire::kFrameHeaderSize + f.header.payload_length;
  img[f.offset + 30] ^= 0x10;
  EXPECT_THAT(read_error(img), HasSubstr("x.fscan: at byte " + std::to_string(crc_at) + ": bad CRC-32C"));
}

TEST(ScanFileErrors, UnknownProtocolVersionInFrame) {
  auto img = sample_image();
  img[kScanFileHeaderSize + 4] = 7;
  EXPECT_THAT(read_error(img), HasSubstr("x.fscan: at byte 20: unsupported protocol version 7.0"));
}

}  // namespace
