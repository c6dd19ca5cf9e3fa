// Scans: assembling from messages (complete, partial, superseded, orphans), .fscan files through
// load_cloud, export round trip.
#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>

#include "common/error.hpp"
#include "common/scan_file.hpp"
#include "common/wire.hpp"
#include "host/io/cloud_writers.hpp"
#include "host/io/load.hpp"
#include "host/io/scan_assembler.hpp"
#include "synth_scan.hpp"

namespace fs::host {
namespace {

msg::Stripe as_message(const fs::test::SynthStripe& s) {
  msg::Stripe m;
  m.header = s.header;
  m.points = std::span<msg::StripePoint>(const_cast<msg::StripePoint*>(s.points.data()), s.points.size());
  return m;
}

struct Collected {
  std::vector<ScanStatus> status;
  std::vector<std::uint32_t> stripes;
  std::vector<std::uint64_t> ids;
};

ScanAssembler::Callback collect(Collected& c) {
  return [&c](const Scan& s) {
    c.status.push_back(s.status());
    c.stripes.push_back(s.stripes_received());
    c.ids.push_back(s.scan_id());
  };
}

class ScanTest : public ::testing::Test {
 protected:
  void SetUp() override {
    calib = ScannerCalibration::bench_default(40);
    synth = fs::test::synth_flat_scan(calib, calib, 15.0, 0.0, 5, 7, 16);
  }
  ScannerCalibration calib;
  fs::test::SynthScan synth;
};

TEST_F(ScanTest, CompleteScan) {
  Collected c;
  ScanAssembler a(collect(c));
  a.on_scan_begin(synth.begin);
  msg::Heartbeat hb;
  hb.time_ns = 123;
  hb.state = 2;
  a.on_heartbeat(hb);
  for (const auto& s : synth.stripes) a.on_stripe(as_message(s));
  EXPECT_TRUE(a.in_scan());
  a.on_scan_end(synth.end);
  ASSERT_EQ(c.status.size(), 1u);
  EXPECT_EQ(c.status[0], ScanStatus::Complete);
  EXPECT_EQ(c.stripes[0], 40u);
  EXPECT_EQ(a.stats().heartbeats, 1u);
  EXPECT_EQ(a.stats().last_state, 2);
  EXPECT_EQ(a.stats().scans_complete, 1u);
  EXPECT_FALSE(a.in_scan());
  a.end_of_stream();  // nothing in progress: no second delivery
  EXPECT_EQ(c.status.size(), 1u);
}

TEST_F(ScanTest, DisconnectMidScanYieldsPartialScan) {
  Collected c;
  ScanAssembler a(collect(c));
  a.on_scan_begin(synth.begin);
  for (std::size_t i = 0; i < 25; ++i) a.on_stripe(as_message(synth.stripes[i]));
  a.end_of_stream();
  ASSERT_EQ(c.status.size(), 1u);
  EXPECT_EQ(c.status[0], ScanStatus::Disconnected);
  EXPECT_EQ(c.stripes[0], 25u);
  EXPECT_EQ(a.stats().scans_partial, 1u);
  // The partial scan triangulates into the columns it has.
  OrganizedCloud cloud;
  Triangulator tri(calib);
  const auto st = tri.triangulate(a.current(), cloud);
  EXPECT_GT(st.points, 0u);
  std::size_t valid_late = 0;
  for (std::uint32_t r = 0; r < cloud.height; ++r)
    for (std::uint32_t k = 25; k < 40; ++k) valid_late += OrganizedCloud::valid(cloud.at(r, k)) ? 1 : 0;
  EXPECT_EQ(valid_late, 0u);
}

TEST_F(ScanTest, MissingStripesAbortSupersedeAndOrphans) {
  Collected c;
  ScanAssembler a(collect(c));
  // Stripe before any ScanBegin: orphan.
  a.on_stripe(as_message(synth.stripes[0]));
  EXPECT_EQ(a.stats().orphan_stripes, 1u);
  // Scan with a gap.
  a.on_scan_begin(synth.begin);
  for (std::size_t i = 0; i < synth.stripes.size(); ++i)
    if (i != 3) a.on_stripe(as_message(synth.stripes[i]));
  a.on_scan_end(synth.end);
  // Aborted scan.
  a.on_scan_begin(synth.begin);
  a.on_stripe(as_message(synth.stripes[0]));
  auto end = synth.end;
  end.completed = 0;
  a.on_scan_end(end);
  // Superseded: a new ScanBegin while a scan is running.
  a.on_scan_begin(synth.begin);
  auto next = synth.begin;
  next.scan_id = 8;
  a.on_scan_begin(next);
  // A stripe of the old scan id is an orphan now; a duplicate step is counted.
  a.on_stripe(as_message(synth.stripes[1]));
  auto dup = synth.stripes[2];
  dup.header.scan_id = 8;
  a.on_stripe(as_message(dup));
  a.on_stripe(as_message(dup));
  EXPECT_EQ(a.current().duplicate_stripes(), 1u);
  auto end8 = synth.end;
  end8.scan_id = 8;
  a.on_scan_end(end8);
  ASSERT_EQ(c.status.size(), 4u);
  EXPECT_EQ(c.status[0], ScanStatus::MissingStripes);
  EXPECT_EQ(c.stripes[0], 39u);
  EXPECT_EQ(c.status[1], ScanStatus::Aborted);
  EXPECT_EQ(c.status[2], ScanStatus::Superseded);
  EXPECT_EQ(c.status[3], ScanStatus::MissingStripes);
  EXPECT_EQ(c.ids[3], 8u);
  EXPECT_EQ(a.stats().orphan_stripes, 2u);
}

TEST_F(ScanTest, RejectsAbsurdScanBegin) {
  ScanAssembler a([](const Scan&) {});
  auto bad = synth.begin;
  bad.calibration.step_count = 0;
  EXPECT_THROW(a.on_scan_begin(bad), fs::Error);
  bad.calibration.step_count = 10'000'000;
  EXPECT_THROW(a.on_scan_begin(bad), fs::Error);
}

class TempDir {
 public:
  TempDir()
      : path_(std::filesystem::temp_directory_path() /
              ("fs_io_" + std::to_string(::getpid()) + "_" + std::to_string(counter_++))) {
    std::filesystem::create_directories(path_);
  }
  ~TempDir() { std::filesystem::remove_all(path_); }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  static inline int counter_ = 0;
  std::filesystem::path path_;
};

void write_fscan(const std::string& path, const fs::test::SynthScan& s, std::size_t stripes, bool with_end) {
  ScanFileWriter file{std::filesystem::path(path)};
  wire::FrameWriter w(file);
  w.send(s.begin);
  msg::Heartbeat hb;
  w.send(hb);
  for (std::size_t i = 0; i < stripes; ++i) w.send(as_message(s.stripes[i]));
  if (with_end) w.send(s.end);
  file.close();
}

TEST_F(ScanTest, FscanFileLoadsAsTriangulatedCloudAndExports) {
  TempDir dir;
  const auto path = dir.file("flat.fscan");
  write_fscan(path, synth, synth.stripes.size(), true);
  OrganizedCloud cloud;
  const auto info = load_cloud(path, cloud);
  EXPECT_EQ(info.format, "fscan");
  EXPECT_TRUE(info.complete_scan);
  EXPECT_EQ(info.scale, 1.0);
  EXPECT_EQ(cloud.width, 40u);
  EXPECT_EQ(cloud.height, 1024u);
  EXPECT_GT(info.valid_points, 40u * 50);
  for (const auto& p : cloud.points) {
    if (OrganizedCloud::valid(p)) {
      ASSERT_NEAR(p.z(), 15.0f, 1e-3);
    }
  }
  // Export and read back both formats.
  for (const char* name : {"out.pcd", "out.ply"}) {
    write_cloud(dir.file(name), cloud);
    OrganizedCloud back;
    LoadOptions mm;
    mm.units = Units::Millimetres;
    load_cloud(dir.file(name), back, mm);
    ASSERT_EQ(back.width, cloud.width);
    ASSERT_EQ(back.height, cloud.height);
    EXPECT_EQ(back.valid_count(), cloud.valid_count());
    EXPECT_EQ(back.points[cloud.index(512, 20)], cloud.points[cloud.index(512, 20)]);
  }
  // A file cut mid-scan loads as a partial scan.
  const auto cut = dir.file("cut.fscan");
  write_fscan(cut, synth, 10, false);
  const auto pinfo = load_cloud(cut, cloud);
  EXPECT_FALSE(pinfo.complete_scan);
  EXPECT_EQ(pinfo.scan_status, "disconnected before ScanEnd");
}

TEST_F(ScanTest, CorruptFscanNamesFileAndOffset) {
  TempDir dir;
  const auto path = dir.file("bad.fscan");
  write_fscan(path, synth, 5, true);
  // Flip a byte inside the 3rd frame's payload: CRC mismatch.
  {
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(2000);
    char c = 0;
    f.read(&c, 1);
    f.seekp(2000);
    c = static_cast<char>(c ^ 0x5a);
    f.write(&c, 1);
  }
  OrganizedCloud cloud;
  try {
    load_cloud(path, cloud);
    ADD_FAILURE() << "no error";
  } catch (const fs::Error& e) {
    EXPECT_NE(std::string(e.what()).find("bad.fscan"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("at byte"), std::string::npos) << e.what();
  }
  EXPECT_THROW(load_cloud(dir.file("none.fscan"), cloud), fs::Error);
}

}  // namespace
}  // namespace fs::host
