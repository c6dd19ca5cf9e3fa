// The memory budget of a scan (ScanLimits): refusals at ScanBegin before allocating, the triangulator's
// camera check, point storage that grows instead of dropping points (several points per row), the
// OverBudget status, a hostile .fscan refused with file and offset, releasing memory after a large scan,
// and the byte-size parser of --memory-budget.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <functional>
#include <string>

#include "common/alloc_counter/alloc_counter.hpp"
#include "common/byte_size.hpp"
#include "common/error.hpp"
#include "common/scan_file.hpp"
#include "host/io/load.hpp"
#include "host/io/scan.hpp"
#include "host/io/scan_assembler.hpp"
#include "host/io/scan_limits.hpp"
#include "host/io/triangulate.hpp"
#include "synth_scan.hpp"

namespace fs::host {
namespace {

using ::testing::HasSubstr;

constexpr std::uint64_t GiB = std::uint64_t(1) << 30;
constexpr std::uint64_t MiB = std::uint64_t(1) << 20;

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

msg::Stripe as_message(const fs::test::SynthStripe& s) {
  msg::Stripe m;
  m.header = s.header;
  m.points = std::span<msg::StripePoint>(const_cast<msg::StripePoint*>(s.points.data()), s.points.size());
  return m;
}

void fill(const fs::test::SynthScan& s, Scan& scan, const ScanLimits& limits) {
  scan.start(s.begin, limits);
  for (const auto& st : s.stripes) scan.add_stripe(as_message(st));
  scan.finish(s.end);
}

// A copy of `s` with a second point in every row of every stripe: 25 px to the right, `second_peak` bright
// (the first point has peak 100).
fs::test::SynthScan with_second_point_per_row(const fs::test::SynthScan& s, std::uint16_t second_peak) {
  fs::test::SynthScan d;
  d.begin = s.begin;
  d.end = s.end;
  for (const auto& st : s.stripes) {
    fs::test::SynthStripe o;
    o.header = st.header;
    for (const auto& p : st.points) {
      msg::StripePoint a = p, b = p;
      a.peak = 100;
      b.col = p.col + 25.0f;
      b.peak = second_peak;
      o.points.push_back(a);
      o.points.push_back(b);
    }
    d.stripes.push_back(std::move(o));
  }
  return d;
}

class TempDir {
 public:
  TempDir()
      : path_(std::filesystem::temp_directory_path() /
              ("fs_limits_" + std::to_string(::getpid()) + "_" + std::to_string(counter_++))) {
    std::filesystem::create_directories(path_);
  }
  ~TempDir() { std::filesystem::remove_all(path_); }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  static inline int counter_ = 0;
  std::filesystem::path path_;
};

// The ScanBegin of issue #25: 65,536 steps x 16,384 rows (a 1280-column camera).
msg::ScanBegin hostile_begin() {
  msg::ScanBegin b;
  b.scan_id = 7;
  b.scanner_model = "hostile";
  b.calibration = ScannerCalibration::bench_default(65536);
  b.calibration.camera.height = 16384;
  return b;
}

TEST(ScanLimits, DefaultsComeFromTheDefaultBudgetAndAcceptTheNormalScan) {
  const ScanLimits d;
  const ScanLimits b = ScanLimits::for_budget(ScanLimits::kDefaultBudgetBytes);
  EXPECT_EQ(d.budget_bytes, 2 * GiB);
  EXPECT_EQ(d.threads, b.threads);
  EXPECT_EQ(d.max_cells, b.max_cells);
  EXPECT_EQ(d.max_ray_table_entries, b.max_ray_table_entries);
  EXPECT_EQ(d.max_total_points, b.max_total_points);
  EXPECT_EQ(ScanLimits::for_budget(0).max_cells, d.max_cells);  // 0 = the default budget
  // The normal hw-sim scan (500 steps x 1024 rows x 1280 columns) uses under a third of the budget, even with
  // 16 recognizer threads (about 570 MiB).
  const auto normal = ScannerCalibration::bench_default(500);
  const ScanLimits sixteen = ScanLimits::for_budget(0, 16);
  EXPECT_LT(sixteen.bytes(500, 1024, 1280, 500 * 1024), sixteen.budget_bytes / 3);
  msg::ScanBegin begin;
  begin.calibration = normal;
  EXPECT_NO_THROW(d.check(begin));
  EXPECT_NO_THROW(sixteen.check(begin));
  // Even the wire's maximum (8192 points in every stripe) fits.
  EXPECT_EQ(sixteen.point_capacity(normal), 500u * msg::kMaxStripePoints);
  // The model grows with the threads and the budget scales the limits.
  EXPECT_GT(ScanLimits::for_budget(0, 16).bytes(500, 1024, 1280, 0),
            ScanLimits::for_budget(0, 1).bytes(500, 1024, 1280, 0));
  EXPECT_LT(ScanLimits::for_budget(512 * MiB, 1).max_cells, ScanLimits::for_budget(2 * GiB, 1).max_cells);
  EXPECT_THROW(ScanLimits::for_budget(ScanLimits::fixed_bytes(1), 1), Error);
  // Every other row segmented (--segment-row-step 2) costs the thinned cloud and segmenter per cell.
  const ScanLimits thin = ScanLimits::for_budget(2 * GiB, 1, 2), every = ScanLimits::for_budget(2 * GiB, 1);
  EXPECT_EQ(thin.segment_row_step, 2u);
  EXPECT_EQ(every.segment_row_step, 1u);
  EXPECT_EQ(thin.bytes(500, 1024, 1280, 0) - every.bytes(500, 1024, 1280, 0),
            500u * 1024u * ScanLimits::kRowThinningBytesPerCell);
  EXPECT_LT(thin.max_cells, every.max_cells);
}

TEST(ScanLimits, HugeScanBeginIsRefusedBeforeAllocating) {
  Scan scan;
  scan.reserve(10, 1000);
  const std::uint64_t held = scan.storage_bytes();
  const msg::ScanBegin begin = hostile_begin();
  fs::AllocCounter counter;
  const std::string what = message_of([&] { scan.start(begin, ScanLimits::for_budget(2 * GiB, 2)); });
  EXPECT_THAT(what, HasSubstr("ScanBegin of scan 7"));
  EXPECT_THAT(what, HasSubstr("step_count 65536 x camera height 16384"));
  EXPECT_THAT(what, HasSubstr("memory budget of 2 GiB (--memory-budget)"));
  EXPECT_THAT(what, HasSubstr("GiB, above"));
  // Nothing beyond the message: far less than the 16 M-point reservation the old code made.
  EXPECT_LT(counter.bytes(), 64u * 1024) << what;
  EXPECT_EQ(scan.storage_bytes(), held);
  EXPECT_FALSE(scan.started());
  // Through the assembler (what every ScanBegin of the stream and of .fscan files goes through).
  ScanAssembler a([](const Scan&) {});
  EXPECT_THAT(message_of([&] { a.on_scan_begin(begin); }), HasSubstr("ScanBegin of scan 7"));
  EXPECT_FALSE(a.in_scan());
}

TEST(ScanLimits, ScanThatFitsOneBudgetButNotASmallerOne) {
  msg::ScanBegin begin;
  begin.scan_id = 3;
  begin.calibration = ScannerCalibration::bench_default(4000);  // 4000 x 1024 = 4 M cells
  const ScanLimits big = ScanLimits::for_budget(2 * GiB, 1);
  const ScanLimits small = ScanLimits::for_budget(512 * MiB, 1);
  EXPECT_NO_THROW(big.check(begin));
  const std::string what = message_of([&] { small.check(begin); });
  EXPECT_THAT(what, HasSubstr("ScanBegin of scan 3: step_count 4000 x camera height 1024 (4096000 cells"));
  EXPECT_THAT(what, HasSubstr("above the memory budget of 512 MiB"));
  // Its model is what the message names.
  EXPECT_THAT(what, HasSubstr("~" + format_byte_size(small.bytes(4000, 1024, 1280, 4000 * 1024))));
}

TEST(ScanLimits, HugeCameraIsRefusedByScanBeginAndByTheTriangulator) {
  // 16,384 x 16,384: a 268 M-entry (3 GiB) ray table.
  msg::ScanBegin begin;
  begin.scan_id = 9;
  begin.calibration = ScannerCalibration::bench_default(10);
  begin.calibration.camera.width = 16384;
  begin.calibration.camera.height = 16384;
  const ScanLimits limits = ScanLimits::for_budget(2 * GiB, 1);
  Scan scan;
  const std::string what = message_of([&] { scan.start(begin, limits); });
  EXPECT_THAT(what, HasSubstr("ScanBegin of scan 9: camera 16384 x 16384 needs a ray table of ~3 GiB"));
  EXPECT_THAT(what, HasSubstr("above the memory budget of 2 GiB"));
  EXPECT_EQ(scan.storage_bytes(), 0u);

  TriangulationOptions options;
  options.limits = limits;
  Triangulator tri;
  fs::AllocCounter counter;
  const std::string t = message_of([&] { tri.configure(begin.calibration, options); });
  EXPECT_THAT(t, HasSubstr("calibration: camera 16384 x 16384 needs a ray table of ~3 GiB"));
  EXPECT_LT(counter.bytes(), 64u * 1024);
  EXPECT_EQ(tri.table_bytes(), 0u);
  EXPECT_FALSE(tri.configured());
  // A larger budget takes it; beyond the hard cap of 16384 pixels per side nothing does.
  options.limits = ScanLimits::for_budget(8 * GiB, 1);
  EXPECT_NO_THROW(options.limits.check_camera(begin.calibration, "calibration"));
  begin.calibration.camera.width = 20000;
  EXPECT_THAT(message_of([&] { options.limits.check_camera(begin.calibration, "calibration"); }),
              HasSubstr("calibration: camera 20000 x 16384 outside 1..16384"));
}

TEST(ScanLimits, TwoPointsPerRowKeepEveryPointAndCountTheSharedCells) {
  const auto calib = ScannerCalibration::bench_default(40);
  const auto one = fs::test::synth_flat_scan(calib, calib, 15.0, 0.0, 5, 7);
  const auto two_dim = with_second_point_per_row(one, 50);      // the first point of each row is brighter
  const auto two_bright = with_second_point_per_row(one, 200);  // the second one is
  std::uint64_t points = 0;
  for (const auto& st : two_dim.stripes) points += st.points.size();
  ASSERT_GT(points, 40000u);

  Scan scan;
  fill(two_dim, scan, {});
  EXPECT_EQ(scan.status(), ScanStatus::Complete) << to_string(scan.status());
  EXPECT_EQ(scan.points_stored(), points) << "every point kept";
  EXPECT_EQ(scan.stripes_rejected(), 0u);
  EXPECT_EQ(scan.stripes_over_budget(), 0u);
  for (std::uint32_t k = 0; k < scan.slot_count(); ++k)
    ASSERT_EQ(scan.stripe_points(k).size(), two_dim.stripes[k].points.size());

  // One cell per (row, step): the brightest point of a row stays, the other is counted.
  TriangulationOptions raw;
  raw.smooth_half_window = 0;  // compare point for point
  Triangulator tri(calib, raw);
  OrganizedCloud cloud, reference, shifted;
  const TriangulationStats st = tri.triangulate(scan, cloud);
  EXPECT_EQ(st.points + st.shared_cell + st.out_of_image + st.grazing + st.out_of_range, points);
  EXPECT_GT(st.shared_cell, points / 3);
  Scan first_only;
  fill(one, first_only, {});
  const TriangulationStats ref = tri.triangulate(first_only, reference);
  EXPECT_EQ(ref.shared_cell, 0u);
  EXPECT_EQ(st.points, ref.points);
  ASSERT_EQ(cloud.points.size(), reference.points.size());
  for (std::size_t i = 0; i < cloud.points.size(); ++i)
    if (OrganizedCloud::valid(reference.points[i])) {
      ASSERT_EQ(cloud.points[i], reference.points[i]) << i;
    }
  // The brighter second point wins where it triangulates: the cloud differs from the first points'.
  Scan bright;
  fill(two_bright, bright, {});
  const TriangulationStats sb = tri.triangulate(bright, shifted);
  EXPECT_GT(sb.shared_cell, points / 3);
  std::size_t moved = 0;
  for (std::size_t i = 0; i < shifted.points.size(); ++i)
    moved += OrganizedCloud::valid(shifted.points[i]) && OrganizedCloud::valid(reference.points[i]) &&
                     shifted.points[i] != reference.points[i]
                 ? 1
                 : 0;
  EXPECT_GT(moved, sb.shared_cell / 2);

  // After warm-up the same scan allocates nothing (the point buffer grew once).
  fs::AllocCounter counter;
  fill(two_dim, scan, {});
  tri.triangulate(scan, cloud);
  EXPECT_EQ(counter.allocations(), 0u);
}

TEST(ScanLimits, StripesBeyondThePointBudgetAreCountedAndTheScanSaysSo) {
  const auto calib = ScannerCalibration::bench_default(40);
  const auto one = fs::test::synth_flat_scan(calib, calib, 15.0, 0.0, 5, 7);
  const auto two = with_second_point_per_row(one, 50);
  // A budget with room for the scan and 1.5 points per cell.
  const std::uint64_t cells = 40ull * 1024;
  const std::uint64_t budget = ScanLimits::scan_bytes(40, 1024, 1280, cells + cells / 2, 1);
  const ScanLimits limits = ScanLimits::for_budget(budget, 1);
  Scan scan;
  fill(two, scan, limits);
  EXPECT_EQ(scan.point_capacity(), cells + cells / 2);
  EXPECT_GT(scan.stripes_over_budget(), 0u);
  EXPECT_EQ(scan.stripes_rejected(), scan.stripes_over_budget());
  EXPECT_LE(scan.points_stored(), scan.point_capacity());
  EXPECT_EQ(scan.status(), ScanStatus::OverBudget);
  EXPECT_STREQ(to_string(scan.status()), "stripe points above the memory budget");
  // The same scan with one point per row fits.
  fill(one, scan, limits);
  EXPECT_EQ(scan.status(), ScanStatus::Complete);
  // A real gap is still MissingStripes.
  scan.start(one.begin, limits);
  for (std::size_t i = 1; i < one.stripes.size(); ++i) scan.add_stripe(as_message(one.stripes[i]));
  scan.finish(one.end);
  EXPECT_EQ(scan.status(), ScanStatus::MissingStripes);

  // Offline: load_cloud reports it.
  TempDir dir;
  const auto path = dir.file("two.fscan");
  {
    ScanFileWriter file{std::filesystem::path(path)};
    wire::FrameWriter w(file);
    w.send(two.begin);
    for (const auto& st : two.stripes) w.send(as_message(st));
    w.send(two.end);
    file.close();
  }
  OrganizedCloud cloud;
  LoadOptions lo;
  lo.limits = limits;
  const LoadInfo info = load_cloud(path, cloud, lo);
  EXPECT_FALSE(info.complete_scan);
  EXPECT_EQ(info.scan_status, "stripe points above the memory budget");
  EXPECT_GT(info.stripes_over_budget, 0u);
  // With the default budget every point is kept and the shared cells are reported.
  const LoadInfo all = load_cloud(path, cloud);
  EXPECT_TRUE(all.complete_scan);
  std::uint64_t points = 0;
  for (const auto& st : two.stripes) points += st.points.size();
  EXPECT_EQ(all.stripe_points, points);
  EXPECT_GT(all.triangulation.shared_cell, 0u);
}

TEST(ScanLimits, HostileFscanIsRefusedWithFileAndOffset) {
  TempDir dir;
  const auto path = dir.file("hostile.fscan");
  {
    ScanFileWriter file{std::filesystem::path(path)};
    wire::FrameWriter w(file);
    msg::Heartbeat hb;
    w.send(hb);  // the ScanBegin is not the first frame: its offset is named
    w.send(hostile_begin());
    file.close();
  }
  EXPECT_LT(std::filesystem::file_size(path), 1024u);
  OrganizedCloud cloud;
  fs::AllocCounter counter;
  const std::string what = message_of([&] { load_cloud(path, cloud); });
  EXPECT_THAT(what,
              HasSubstr(path + ": at byte 53: ScanBegin of scan 7: step_count 65536 x camera height 16384"));
  EXPECT_THAT(what, HasSubstr("above the memory budget of 2 GiB (--memory-budget)"));
  EXPECT_LT(counter.bytes(), 16u * MiB) << "refused before the scan's storage is allocated";
  EXPECT_EQ(cloud.points.capacity(), 0u);
  // The same through read_scan_file with a larger budget: still far above.
  EXPECT_THAT(message_of([&] {
                read_scan_file(
                    path, [](const Scan&) {}, ScanLimits::for_budget(64 * GiB));
              }),
              HasSubstr("memory budget of 64 GiB"));
}

TEST(ScanLimits, MemoryOfALargeScanIsReturned) {
  const auto calib = ScannerCalibration::bench_default(40);
  const auto one = fs::test::synth_flat_scan(calib, calib, 15.0, 0.0, 5, 7);
  Scan scan;
  fill(one, scan, {});
  Triangulator tri(calib);
  OrganizedCloud cloud;
  tri.triangulate(scan, cloud);
  // Within the usual working size (the normal scan): nothing to do, nothing allocated.
  {
    fs::AllocCounter counter;
    EXPECT_EQ(release_scan_memory(scan, tri, &cloud), 0u);
    EXPECT_EQ(counter.allocations(), 0u);
  }
  // Larger than a working size of 10 steps x 100 rows x 100 columns: released.
  const WorkingSize small{10, 100, 100};
  const std::uint64_t held = scan.storage_bytes() + tri.table_bytes();
  const std::uint64_t freed = release_scan_memory(scan, tri, &cloud, small);
  EXPECT_GT(freed, held / 2);
  EXPECT_LE(scan.storage_bytes(), ScanLimits::scan_storage_bytes(10, 1000));
  EXPECT_EQ(tri.table_bytes(), 0u);
  EXPECT_FALSE(tri.configured());
  EXPECT_EQ(cloud.points.capacity(), 0u);
  EXPECT_EQ(scan.slot_count(), 0u) << "the released scan is emptied";
  EXPECT_EQ(release_scan_memory(scan, tri, &cloud, small), 0u);
  // Both work again afterwards.
  fill(one, scan, {});
  EXPECT_EQ(scan.status(), ScanStatus::Complete);
  EXPECT_GT(tri.triangulate(scan, cloud).points, 40u * 500);
}

TEST(ByteSize, ParsesAndFormats) {
  EXPECT_EQ(parse_byte_size("2147483648"), 2 * GiB);
  EXPECT_EQ(parse_byte_size("512M"), 512 * MiB);
  EXPECT_EQ(parse_byte_size("512m"), 512 * MiB);
  EXPECT_EQ(parse_byte_size("512MiB"), 512 * MiB);
  EXPECT_EQ(parse_byte_size("512MB"), 512 * MiB);
  EXPECT_EQ(parse_byte_size("2G"), 2 * GiB);
  EXPECT_EQ(parse_byte_size("1.5G"), 3 * GiB / 2);
  EXPECT_EQ(parse_byte_size("64k"), 65536u);
  EXPECT_EQ(parse_byte_size("1T"), 1024 * GiB);
  EXPECT_EQ(parse_byte_size("100B"), 100u);
  for (const char* bad : {"", "-1", "G", "2X", "2 G", "1.5", "2GG", "99999999999999999999", "16777216T"})
    EXPECT_THAT(message_of([&] { parse_byte_size(bad); }), HasSubstr("byte size '" + std::string(bad) + "'"))
        << bad;
  EXPECT_EQ(format_byte_size(512), "512 B");
  EXPECT_EQ(format_byte_size(2 * GiB), "2 GiB");
  EXPECT_EQ(format_byte_size(3 * GiB / 2), "1.5 GiB");
  EXPECT_EQ(format_byte_size(150 * GiB + 300 * MiB), "150 GiB");
  EXPECT_EQ(format_byte_size(16 * 1024), "16 KiB");
}

}  // namespace
}  // namespace fs::host
