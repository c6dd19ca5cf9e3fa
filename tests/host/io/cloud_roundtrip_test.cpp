// Export round trips: a scan exported to PLY and PCD (every encoding) and read back gives the same organized
// cloud, point by point, with the same sensor viewpoint. (A PLY read back without its viewpoint segmented
// into ~1000 regions instead of 5: segmentation orients normals toward the viewpoint and scales its noise
// model by the range from it.) Also: the PLY viewpoint comment and PCL's camera element on input.
#include <gtest/gtest.h>

#include <unistd.h>
#include <cstring>
#include <filesystem>
#include <sstream>

#include "common/error.hpp"
#include "fscan_file.hpp"
#include "host/io/cloud_readers.hpp"
#include "host/io/cloud_writers.hpp"
#include "host/io/io_tools.hpp"
#include "host/io/load.hpp"

namespace fs::host {
namespace {

std::span<const std::byte> bytes_of(const std::string& s) {
  return {reinterpret_cast<const std::byte*>(s.data()), s.size()};
}

struct TempDir {
  std::filesystem::path p =
      std::filesystem::temp_directory_path() / ("fs_io_rt_" + std::to_string(::getpid()));
  TempDir() { std::filesystem::create_directories(p); }
  ~TempDir() { std::filesystem::remove_all(p); }
  std::string operator()(const std::string& n) const { return (p / n).string(); }
};

// Same grid, same NaN cells, bit-identical points, same labels and viewpoint.
void expect_identical(const OrganizedCloud& a, const OrganizedCloud& b, const std::string& what) {
  SCOPED_TRACE(what);
  ASSERT_EQ(a.width, b.width);
  ASSERT_EQ(a.height, b.height);
  EXPECT_EQ(a.organized, b.organized);
  ASSERT_EQ(a.points.size(), b.points.size());
  std::size_t differ = 0;
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    const bool va = OrganizedCloud::valid(a.points[i]), vb = OrganizedCloud::valid(b.points[i]);
    if (va != vb || (va && std::memcmp(a.points[i].data(), b.points[i].data(), sizeof(float) * 3) != 0))
      ++differ;
  }
  EXPECT_EQ(differ, 0u) << "cells differing";
  EXPECT_EQ(a.labels, b.labels);
  EXPECT_EQ(a.viewpoint, b.viewpoint);
  EXPECT_NEAR(a.viewpoint_orientation.angularDistance(b.viewpoint_orientation), 0.0, 1e-12);
}

TEST(ExportRoundTrip, ScanToPlyAndPcdReadsBackTheSameOrganizedCloud) {
  TempDir dir;
  // A flat scan with holes: every 4th row only, and a gap of missing stripes.
  const auto calib = ScannerCalibration::bench_default(48);
  auto synth = fs::test::synth_flat_scan(calib, calib, 12.0, 0.05, 5, 1, 4);
  for (std::size_t k = 20; k < 24; ++k) synth.stripes[k].points.clear();
  fs::test::write_fscan(dir("scan.fscan"), synth);
  OrganizedCloud ref;
  const LoadInfo ref_info = load_cloud(dir("scan.fscan"), ref);
  ASSERT_EQ(ref.width, 48u);
  ASSERT_EQ(ref.height, 1024u);
  EXPECT_GT(ref_info.valid_points, 48u * 200);
  EXPECT_LT(ref_info.valid_points, ref.points.size() / 2) << "the grid must have holes";
  EXPECT_EQ(ref.viewpoint, calib.camera.center());
  EXPECT_STREQ(segment_profile_for(ref_info), "laser");
  ASSERT_GT(ref.viewpoint.norm(), 100.0) << "a viewpoint a lost one (0) cannot pass for";

  struct Case {
    std::string file;
    PcdEncoding pcd;
    bool ply_ascii;
  };
  const Case cases[] = {{"b.ply", PcdEncoding::Binary, false},
                        {"a.ply", PcdEncoding::Binary, true},
                        {"c.pcd", PcdEncoding::BinaryCompressed, false},
                        {"b.pcd", PcdEncoding::Binary, false},
                        {"a.pcd", PcdEncoding::Ascii, false}};
  for (const Case& c : cases) {
    ExportArgs args;
    args.input = dir("scan.fscan");
    args.output = dir(c.file);
    args.pcd_encoding = c.pcd;
    args.write.ply_ascii = c.ply_ascii;
    std::ostringstream log;
    run_export(args, log);
    OrganizedCloud back;
    const LoadInfo info = load_cloud(args.output, back);
    EXPECT_EQ(info.scale, 1.0) << c.file;
    EXPECT_STREQ(segment_profile_for(info), "laser") << c.file << ": a laser scan stays a laser scan";
    EXPECT_EQ(info.valid_points, ref_info.valid_points) << c.file;
    expect_identical(ref, back, c.file);
    // And once more through the other format (PLY -> PCD -> PLY keeps everything).
    ExportArgs again;
    again.input = args.output;
    again.output = dir(c.file.substr(0, 1) + "_again" + (c.file.ends_with(".ply") ? ".pcd" : ".ply"));
    run_export(again, log);
    OrganizedCloud back2;
    load_cloud(again.output, back2);
    expect_identical(ref, back2, again.output);
  }
}

TEST(ExportRoundTrip, PlyViewpointIsScaledWithTheUnits) {
  OrganizedCloud c;
  c.reset(2, 2);
  c.at(0, 0) = Eigen::Vector3f(0.1f, 0.2f, 0.3f);
  c.at(1, 1) = Eigen::Vector3f(-0.1f, 0.2f, 0.9f);
  c.viewpoint = Eigen::Vector3d(0.0, 0.0, 0.5);
  c.viewpoint_orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Vec3::UnitX()));
  TempDir dir;
  write_cloud(dir("m.ply"), c);
  OrganizedCloud back;
  const LoadInfo info = load_cloud(dir("m.ply"), back);  // auto units: metres
  EXPECT_EQ(info.scale, 1000.0);
  EXPECT_STREQ(segment_profile_for(info), "kinect");
  EXPECT_NEAR((back.viewpoint - Vec3(0, 0, 500)).norm(), 0.0, 1e-9);
  EXPECT_NEAR(back.viewpoint_orientation.angularDistance(c.viewpoint_orientation), 0.0, 1e-12);
}

TEST(PlyViewpoint, FromPclCameraElementAndMalformedComment) {
  const std::string grid = "obj_info num_cols 2\nobj_info num_rows 1\n";
  const std::string vertices = "element vertex 2\nproperty float x\nproperty float y\nproperty float z\n";
  const std::string camera =
      "element camera 1\nproperty float view_px\nproperty float view_py\nproperty float view_pz\n"
      "property float x_axisx\nproperty float focal\n";
  OrganizedCloud c;
  read_ply(bytes_of("ply\nformat ascii 1.0\n" + grid + vertices + camera +
                    "end_header\n1 2 3\n4 5 6\n"
                    "10 20 30 1 525\n"),
           "pcl.ply", c);
  EXPECT_EQ(c.viewpoint, Vec3(10, 20, 30));
  EXPECT_EQ(c.at(0, 1), Eigen::Vector3f(4, 5, 6));
  // The element before the vertices works too.
  read_ply(bytes_of("ply\nformat ascii 1.0\n" + grid + camera + vertices +
                    "end_header\n-1 -2 -3 1 525\n1 2 3\n"
                    "4 5 6\n"),
           "pcl2.ply", c);
  EXPECT_EQ(c.viewpoint, Vec3(-1, -2, -3));
  // Without any: the origin (PCL's default sensor origin), as before.
  read_ply(bytes_of("ply\nformat ascii 1.0\n" + grid + vertices + "end_header\n1 2 3\n4 5 6\n"), "none.ply",
           c);
  EXPECT_EQ(c.viewpoint, Vec3::Zero());
  // Other comments are free text; ours must be well formed and finite.
  read_ply(bytes_of("ply\nformat ascii 1.0\ncomment viewpoint of the sensor: unknown\n" + grid + vertices +
                    "end_header\n1 2 3\n4 5 6\n"),
           "free.ply", c);
  auto expect_error = [&](const std::string& header_line, const std::string& fragment) {
    try {
      read_ply(
          bytes_of("ply\nformat ascii 1.0\n" + header_line + grid + vertices + "end_header\n1 2 3\n4 5 6\n"),
          "bad.ply", c);
      ADD_FAILURE() << "accepted " << header_line;
    } catch (const fs::Error& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find("bad.ply"), std::string::npos) << m;
      EXPECT_NE(m.find("at byte 21"), std::string::npos) << m;  // the comment line's offset
      EXPECT_NE(m.find(fragment), std::string::npos) << m;
    }
  };
  expect_error("comment facetscan_viewpoint 1 2 3\n", "7 values");
  expect_error("comment facetscan_viewpoint 1 2 nan 1 0 0 0\n", "'nan' is not a finite number");
  expect_error("comment facetscan_viewpoint 1 2 x 1 0 0 0\n", "'x' is not a finite number");
  try {
    read_ply(bytes_of("ply\nformat ascii 1.0\n" + grid + vertices + camera +
                      "end_header\n1 2 3\n4 5 6\n"
                      "nan 20 30 1 525\n"),
             "cam.ply", c);
    ADD_FAILURE() << "accepted a NaN camera position";
  } catch (const fs::Error& e) {
    EXPECT_NE(std::string(e.what()).find("camera"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace fs::host
