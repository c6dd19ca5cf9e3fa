// PCD / PLY readers and writers: real mOSD scans, round trips in every encoding, malformed input.
#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <set>
#include <string>

#include "common/error.hpp"
#include "host/io/cloud_readers.hpp"
#include "host/io/cloud_writers.hpp"
#include "host/io/load.hpp"
#include "support/test_paths.hpp"

namespace fs::host {
namespace {

std::span<const std::byte> bytes_of(const std::string& s) {
  return {reinterpret_cast<const std::byte*>(s.data()), s.size()};
}

// Expects fs::Error whose message contains every fragment.
template <typename F>
void expect_error(F&& f, std::initializer_list<std::string> fragments) {
  try {
    f();
    ADD_FAILURE() << "no fs::Error thrown";
  } catch (const fs::Error& e) {
    const std::string msg = e.what();
    for (const auto& frag : fragments) EXPECT_NE(msg.find(frag), std::string::npos) << "message: " << msg;
  }
}

OrganizedCloud small_cloud(bool labels) {
  OrganizedCloud c;
  c.reset(4, 3, labels);
  for (std::uint32_t r = 0; r < 3; ++r)
    for (std::uint32_t col = 0; col < 4; ++col) {
      c.at(r, col) = Eigen::Vector3f(10.5f * col - 3.25f, -2.0f * r + 0.125f, 700.0f + r * col);
      if (labels) c.labels[c.index(r, col)] = static_cast<std::int32_t>(r * 10 + col);
    }
  const float nan = std::numeric_limits<float>::quiet_NaN();
  c.at(1, 2) = Eigen::Vector3f(nan, nan, nan);
  c.viewpoint = Eigen::Vector3d(1, 2, 3);
  return c;
}

void expect_same(const OrganizedCloud& a, const OrganizedCloud& b) {
  ASSERT_EQ(a.width, b.width);
  ASSERT_EQ(a.height, b.height);
  ASSERT_EQ(a.points.size(), b.points.size());
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    ASSERT_EQ(OrganizedCloud::valid(a.points[i]), OrganizedCloud::valid(b.points[i])) << i;
    if (OrganizedCloud::valid(a.points[i])) {
      EXPECT_EQ(a.points[i], b.points[i]) << i;
    }
  }
  EXPECT_EQ(a.labels, b.labels);
}

TEST(Pcd, ReadsRealMosdScanWithLabelsInMillimetres) {
  const auto path = (fs::test::shared_data() / "mosd-boxes/test/test0.pcd").string();
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "missing " << path;
  OrganizedCloud cloud;
  const LoadInfo info = load_cloud(path, cloud);
  EXPECT_EQ(info.format, "pcd");
  EXPECT_EQ(info.scale, 1000.0);  // Kinect clouds are in metres
  EXPECT_EQ(cloud.width, 640u);
  EXPECT_EQ(cloud.height, 480u);
  EXPECT_TRUE(cloud.organized);
  ASSERT_EQ(cloud.labels.size(), cloud.points.size());
  EXPECT_GT(info.valid_points, 50000u);
  EXPECT_LT(info.valid_points, cloud.points.size());
  std::set<std::int32_t> labels;
  double zmin = 1e9, zmax = -1e9;
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    const auto& p = cloud.points[i];
    labels.insert(cloud.labels[i]);
    if (!OrganizedCloud::valid(p)) {
      EXPECT_EQ(cloud.labels[i], 0) << "mOSD: label 0 = NaN points";
      continue;
    }
    zmin = std::min<double>(zmin, p.z());
    zmax = std::max<double>(zmax, p.z());
  }
  EXPECT_GT(zmin, 300.0);  // Kinect range in mm
  EXPECT_LT(zmax, 3000.0);
  EXPECT_TRUE(labels.count(1)) << "table label";
  EXPECT_TRUE(std::any_of(labels.begin(), labels.end(), [](int l) { return l >= 20; })) << "object labels";
  // Organized: neighbouring valid pixels are close in 3D (a few mm at ~1 m), far from random.
  int close = 0, pairs = 0;
  for (std::uint32_t r = 100; r < 380; r += 7)
    for (std::uint32_t c = 100; c < 540; c += 7) {
      const auto &a = cloud.at(r, c), &b = cloud.at(r, c + 1);
      if (!OrganizedCloud::valid(a) || !OrganizedCloud::valid(b)) continue;
      ++pairs;
      close += (a - b).norm() < 20.0f ? 1 : 0;
    }
  ASSERT_GT(pairs, 100);
  EXPECT_GT(close, pairs * 9 / 10);
}

TEST(Pcd, ReadsAllMosdTestScans) {
  const auto dir = fs::test::shared_data() / "mosd-boxes/test";
  if (!std::filesystem::exists(dir)) GTEST_SKIP();
  int n = 0;
  OrganizedCloud cloud;
  cloud.reserve(640 * 480);
  LoadOptions opt;
  opt.units = Units::Metres;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.path().extension() != ".pcd") continue;
    const auto info = load_cloud(e.path().string(), cloud, opt);
    EXPECT_EQ(cloud.width * cloud.height, 307200u) << e.path();
    EXPECT_GT(info.valid_points, 10000u) << e.path();
    ++n;
  }
  EXPECT_EQ(n, 24);
}

TEST(Pcd, RoundTripsEveryEncoding) {
  const OrganizedCloud c = small_cloud(true);
  for (auto enc : {PcdEncoding::Ascii, PcdEncoding::Binary, PcdEncoding::BinaryCompressed}) {
    const std::string s = encode_pcd(c, enc);
    OrganizedCloud back;
    read_pcd(bytes_of(s), "mem.pcd", back);
    expect_same(c, back);
    EXPECT_EQ(back.viewpoint, c.viewpoint);
  }
}

TEST(Pcd, ReadsHandWrittenAsciiWithExtraFieldsAndCounts) {
  const std::string s =
      "# comment\nVERSION .7\nFIELDS normal_x x y z label rgb hist\nSIZE 4 8 4 4 2 4 1\nTYPE F F F F U U U\n"
      "COUNT 1 1 1 1 1 1 3\nWIDTH 2\nHEIGHT 2\nVIEWPOINT 0.5 0 0 1 0 0 0\nPOINTS 4\nDATA ascii\n"
      "0 1 2 3 7 0 1 2 3\n0 4 5 6 8 0 1 2 3\r\n0 nan 5 6 9 0 1 2 3\n0 1e1 2 -3.5 65535 0 1 2 3\n";
  OrganizedCloud c;
  read_pcd(bytes_of(s), "hand.pcd", c);
  ASSERT_EQ(c.width, 2u);
  ASSERT_EQ(c.height, 2u);
  EXPECT_EQ(c.at(0, 0), Eigen::Vector3f(1, 2, 3));
  EXPECT_EQ(c.at(0, 1), Eigen::Vector3f(4, 5, 6));
  EXPECT_FALSE(OrganizedCloud::valid(c.at(1, 0)));
  EXPECT_EQ(c.at(1, 1), Eigen::Vector3f(10, 2, -3.5f));
  EXPECT_EQ(c.labels, (std::vector<std::int32_t>{7, 8, 9, 65535}));
  EXPECT_EQ(c.viewpoint.x(), 0.5);
}

TEST(Pcd, BinaryWithMixedTypesAndPadding) {
  // x as double, y/z float, an int16 label, one padding byte field "_".
  std::string s =
      "VERSION 0.7\nFIELDS x _ y z label\nSIZE 8 1 4 4 2\nTYPE F U F F I\nCOUNT 1 1 1 1 1\n"
      "WIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary\n";
  auto rec = [&](double x, float y, float z, std::int16_t l) {
    s.append(reinterpret_cast<const char*>(&x), 8);
    s.push_back('\x7f');
    s.append(reinterpret_cast<const char*>(&y), 4);
    s.append(reinterpret_cast<const char*>(&z), 4);
    s.append(reinterpret_cast<const char*>(&l), 2);
  };
  rec(1.5, 2.5f, 3.5f, -4);
  rec(-1.0, 0.0f, 9.0f, 12);
  OrganizedCloud c;
  read_pcd(bytes_of(s), "mixed.pcd", c);
  EXPECT_EQ(c.at(0, 0), Eigen::Vector3f(1.5f, 2.5f, 3.5f));
  EXPECT_EQ(c.at(0, 1), Eigen::Vector3f(-1, 0, 9));
  EXPECT_EQ(c.labels, (std::vector<std::int32_t>{-4, 12}));
}

TEST(Pcd, MalformedInputNamesFileAndOffset) {
  const OrganizedCloud c = small_cloud(true);
  const std::string bin = encode_pcd(c, PcdEncoding::Binary);
  const std::string cmp = encode_pcd(c, PcdEncoding::BinaryCompressed);
  const std::string asc = encode_pcd(c, PcdEncoding::Ascii);
  OrganizedCloud out;
  auto read = [&](const std::string& s) { read_pcd(bytes_of(s), "bad.pcd", out); };
  expect_error([&] { read(bin.substr(0, bin.size() - 5)); }, {"bad.pcd", "at byte", "truncated binary data"});
  expect_error([&] { read(cmp.substr(0, cmp.size() - 5)); }, {"bad.pcd", "truncated binary_compressed"});
  expect_error([&] { read(asc.substr(0, asc.size() - 20)); }, {"bad.pcd"});
  expect_error([&] { read(bin.substr(0, 60)); }, {"bad.pcd", "at byte"});
  auto replace = [](std::string s, const std::string& from, const std::string& to) {
    const auto at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, from.size(), to);
  };
  expect_error([&] { read(replace(bin, "POINTS 12", "POINTS 13")); }, {"POINTS 13 != WIDTH x HEIGHT"});
  expect_error([&] { read(replace(bin, "VIEWPOINT 1", "VIEWPOINT nan")); }, {"VIEWPOINT", "not finite"});
  expect_error([&] { read(replace(replace(bin, "WIDTH 4", "WIDTH 4000000000"), "POINTS 12", "POINTS 1")); },
               {"WIDTH", "exceeds the limit"});
  expect_error([&] { read(replace(bin, "SIZE 4 4 4 4", "SIZE 4 4 4")); }, {"SIZE: 3 values for 4 fields"});
  expect_error([&] { read(replace(bin, "FIELDS x y z", "FIELDS a y z")); }, {"must include x, y and z"});
  expect_error([&] { read(replace(bin, "TYPE F", "TYPE Q")); }, {"TYPE of field 'x'"});
  expect_error([&] { read(replace(bin, "DATA binary", "DATA zip")); }, {"DATA 'zip'"});
  expect_error([&] { read(replace(asc, "700 ", "7x0 ")); }, {"is not a number"});
  expect_error([&] { read("PLY\n"); }, {"unknown header keyword"});
  expect_error([&] { read(""); }, {"without a DATA line"});
  // Corrupt the LZF stream itself: a back-reference before the start of the output.
  std::string corrupt = cmp;
  const auto data_at = corrupt.find("DATA binary_compressed\n") + 23;
  corrupt[data_at + 8] = static_cast<char>(0xe0);
  corrupt[data_at + 9] = static_cast<char>(0xff);
  expect_error([&] { read(corrupt); }, {"bad.pcd", "binary_compressed"});
}

TEST(Ply, RoundTripsOrganizedBinaryAndAscii) {
  const OrganizedCloud c = small_cloud(true);
  for (bool ascii : {false, true}) {
    CloudWriteOptions o;
    o.ply_ascii = ascii;
    o.colours_from_labels = true;
    const std::string s = encode_ply(c, o);
    OrganizedCloud back;
    read_ply(bytes_of(s), "mem.ply", back);
    EXPECT_TRUE(back.organized);
    OrganizedCloud expected = c;
    expected.labels[expected.index(1, 2)] = -1;  // PLY stores valid points only: no-data cells lose labels
    expect_same(expected, back);
  }
}

TEST(Ply, BigEndianWithFacesAndGridFromObjInfo) {
  std::string s =
      "ply\nformat binary_big_endian 1.0\ncomment x\nobj_info width 2\nobj_info height 1\n"
      "element vertex 2\nproperty double x\nproperty float y\nproperty float z\nproperty uchar label\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  auto be = [&](auto v) {
    char b[sizeof(v)];
    std::memcpy(b, &v, sizeof(v));
    for (int i = sizeof(v) - 1; i >= 0; --i) s.push_back(b[i]);
  };
  be(1.0);
  be(2.0f);
  be(3.0f);
  be(std::uint8_t{5});
  be(-1.0);
  be(-2.0f);
  be(-3.0f);
  be(std::uint8_t{6});
  be(std::uint8_t{3});
  be(std::int32_t{0});
  be(std::int32_t{1});
  be(std::int32_t{0});
  OrganizedCloud c;
  read_ply(bytes_of(s), "be.ply", c);
  EXPECT_TRUE(c.organized);
  ASSERT_EQ(c.width, 2u);
  EXPECT_EQ(c.at(0, 0), Eigen::Vector3f(1, 2, 3));
  EXPECT_EQ(c.at(0, 1), Eigen::Vector3f(-1, -2, -3));
  EXPECT_EQ(c.labels, (std::vector<std::int32_t>{5, 6}));
}

TEST(Ply, WithoutGridIsFlaggedUnorganized) {
  const std::string s =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n1 2 3\n4 5 6\n7 8 9\n";
  OrganizedCloud c;
  read_ply(bytes_of(s), "u.ply", c);
  EXPECT_FALSE(c.organized);
  EXPECT_EQ(c.width, 3u);
  EXPECT_EQ(c.height, 1u);
  EXPECT_EQ(c.at(0, 2), Eigen::Vector3f(7, 8, 9));
}

TEST(Ply, MalformedInputNamesFileAndOffset) {
  const OrganizedCloud c = small_cloud(true);
  const std::string bin = encode_ply(c);
  CloudWriteOptions ao;
  ao.ply_ascii = true;
  const std::string asc = encode_ply(c, ao);
  OrganizedCloud out;
  auto read = [&](const std::string& s) { read_ply(bytes_of(s), "bad.ply", out); };
  auto replace = [](std::string s, const std::string& from, const std::string& to) {
    const auto at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, from.size(), to);
  };
  expect_error([&] { read(bin.substr(0, bin.size() - 3)); }, {"bad.ply", "at byte", "truncated"});
  expect_error([&] { read(asc.substr(0, asc.size() - 10)); }, {"bad.ply", "at byte"});
  expect_error([&] { read("plx\n"); }, {"not a PLY file"});
  expect_error([&] { read(replace(bin, "element vertex 11", "element vertex 99999999999")); },
               {"exceeds the limit"});
  expect_error([&] { read(replace(bin, "obj_info num_cols 4", "obj_info num_cols 5")); },
               {"range_grid has 12 cells"});
  expect_error([&] { read(replace(bin, "property float x", "property quux x")); }, {"unknown property type"});
  expect_error([&] { read(replace(bin, "end_header", "end_headr")); }, {"unknown header keyword"});
  expect_error([&] { read(replace(asc, "\n-3.25 ", "\nfoo ")); }, {"'foo' is not a number"});
  expect_error([&] { read(replace(bin, "property float x\n", "")); }, {"lacks x, y or z"});
}

TEST(Load, UnitsAndExplicitScale) {
  OrganizedCloud c = small_cloud(false);
  for (auto& p : c.points) p /= 1000.0f;  // now in metres
  const auto dir = std::filesystem::temp_directory_path() / ("fs_io_units_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto path = (dir / "m.pcd").string();
  write_cloud(path, c);
  OrganizedCloud out;
  EXPECT_EQ(load_cloud(path, out).scale, 1000.0);
  EXPECT_NEAR(out.at(0, 0).z(), 700.0f, 1e-3);
  LoadOptions mm;
  mm.units = Units::Millimetres;
  EXPECT_EQ(load_cloud(path, out, mm).scale, 1.0);
  EXPECT_NEAR(out.at(0, 0).z(), 0.7f, 1e-6);
  LoadOptions s;
  s.scale = 25.4;
  EXPECT_EQ(load_cloud(path, out, s).scale, 25.4);
  expect_error([&] { load_cloud((dir / "missing.pcd").string(), out); }, {"missing.pcd", "cannot open"});
  expect_error([&] { load_cloud((dir / "x.xyz").string(), out); }, {"unknown point-cloud format"});
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace fs::host
