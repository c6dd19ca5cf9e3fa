// A Scan written back as .fscan (serve keeps failed scans this way) reads back as the same scan: header,
// every kept stripe (points bit-identical), ScanEnd and status; a lone ScanBegin (a refused scan) too.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>

#include "common/error.hpp"
#include "host/io/scan_assembler.hpp"
#include "host/io/scan_writer.hpp"
#include "synth_scan.hpp"

namespace fs::host {
namespace {

namespace stdfs = std::filesystem;

stdfs::path temp_file(const std::string& name) {
  return stdfs::temp_directory_path() / ("facetscan-scan-writer-" + std::to_string(::getpid()) + "-" + name);
}

Scan partial_scan(const fs::test::SynthScan& s, std::size_t n, bool end) {
  Scan scan;
  scan.start(s.begin);
  for (std::size_t i = 0; i < n; ++i) {
    msg::Stripe m;
    m.header = s.stripes[i].header;
    m.points = std::span<msg::StripePoint>(const_cast<msg::StripePoint*>(s.stripes[i].points.data()),
                                           s.stripes[i].points.size());
    EXPECT_TRUE(scan.add_stripe(m));
  }
  if (end)
    scan.finish(s.end);
  else
    scan.interrupt(ScanStatus::Disconnected);
  return scan;
}

void expect_same(const Scan& a, const Scan& b) {
  EXPECT_EQ(a.scan_id(), b.scan_id());
  EXPECT_EQ(a.status(), b.status());
  EXPECT_EQ(a.slot_count(), b.slot_count());
  EXPECT_EQ(a.stripes_received(), b.stripes_received());
  EXPECT_EQ(a.points_stored(), b.points_stored());
  EXPECT_EQ(a.begin_message().scanner_model, b.begin_message().scanner_model);
  EXPECT_EQ(a.begin_message().calibration.camera.width, b.begin_message().calibration.camera.width);
  EXPECT_EQ(a.has_end(), b.has_end());
  for (std::uint32_t k = 0; k < a.slot_count(); ++k) {
    ASSERT_EQ(a.has_stripe(k), b.has_stripe(k)) << k;
    if (!a.has_stripe(k)) continue;
    EXPECT_EQ(a.stripe_header(k).step_index, b.stripe_header(k).step_index);
    EXPECT_EQ(a.stripe_header(k).capture_time_ns, b.stripe_header(k).capture_time_ns);
    const auto pa = a.stripe_points(k), pb = b.stripe_points(k);
    ASSERT_EQ(pa.size(), pb.size()) << k;
    for (std::size_t i = 0; i < pa.size(); ++i) {
      EXPECT_EQ(pa[i].row, pb[i].row);
      EXPECT_EQ(pa[i].col, pb[i].col);
      EXPECT_EQ(pa[i].peak, pb[i].peak);
      EXPECT_EQ(pa[i].width, pb[i].width);
    }
  }
}

TEST(ScanWriter, APartialScanRoundTrips) {
  const auto calib = ScannerCalibration::bench_default(30);
  const auto synth = fs::test::synth_flat_scan(calib, calib, 12.0, 0.0, 1, 42, 32);
  const Scan scan = partial_scan(synth, 17, false);
  ASSERT_GT(scan.points_stored(), 0u);
  const stdfs::path p = temp_file("partial.fscan");
  write_scan_file(p, scan);
  Scan back;
  load_scan(p.string(), back);
  expect_same(scan, back);
  EXPECT_EQ(back.stripes_received(), 17u);
  stdfs::remove(p);
}

TEST(ScanWriter, ACompleteScanKeepsItsScanEnd) {
  const auto calib = ScannerCalibration::bench_default(30);
  const auto synth = fs::test::synth_flat_scan(calib, calib, 12.0, 0.0, 1, 42, 32);
  const Scan scan = partial_scan(synth, 30, true);
  ASSERT_EQ(scan.status(), ScanStatus::Complete);
  const stdfs::path p = temp_file("complete.fscan");
  write_scan_file(p, scan);
  Scan back;
  load_scan(p.string(), back);
  expect_same(scan, back);
  EXPECT_EQ(back.end_message().stripes_sent, scan.end_message().stripes_sent);
  stdfs::remove(p);
}

TEST(ScanWriter, ALoneScanBeginReadsAsAnEmptyPartialScan) {
  const auto calib = ScannerCalibration::bench_default(30);
  auto synth = fs::test::synth_flat_scan(calib, calib, 12.0, 0.0, 1, 42, 32);
  synth.begin.scan_id = 99;
  const stdfs::path p = temp_file("begin.fscan");
  write_scan_file(p, synth.begin);
  Scan back;
  load_scan(p.string(), back);
  EXPECT_EQ(back.scan_id(), 99u);
  EXPECT_EQ(back.stripes_received(), 0u);
  EXPECT_EQ(back.status(), ScanStatus::Disconnected);
  EXPECT_THROW(write_scan_file(stdfs::path("/nonexistent-dir/x.fscan"), synth.begin), fs::Error);
  stdfs::remove(p);
}

}  // namespace
}  // namespace fs::host
