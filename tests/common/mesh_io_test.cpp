// Mesh readers: every format on a unit cube, and each malformed case with its file/line/offset message.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include "common/error.hpp"
#include "common/mesh_io.hpp"
#include "support/test_paths.hpp"

namespace {

using ::testing::HasSubstr;

const char* kCubeOff = R"(OFF
# unit cube
8 6 12
0 0 0
1 0 0
1 1 0
0 1 0
0 0 1
1 0 1
1 1 1
0 1 1
4 0 3 2 1
4 4 5 6 7
4 0 1 5 4
4 1 2 6 5
4 2 3 7 6
4 3 0 4 7
)";

const char* kCubeObj = R"(# cube
o cube
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
vn 0 0 1
f 1/1/1 4/1/1 3/1/1 2/1/1
f 5//1 6//1 7//1 8//1
f 1 2 6 5
f -7 -6 -2 -3
f 3 4 8 7
f 4 1 5 8
)";

std::string cube_ply_ascii() {
  return "ply\nformat ascii 1.0\ncomment cube\nelement vertex 8\nproperty float x\nproperty float y\n"
         "property float z\nproperty uchar red\nelement face 6\nproperty list uchar int vertex_indices\n"
         "end_header\n0 0 0 1\n1 0 0 1\n1 1 0 1\n0 1 0 1\n0 0 1 1\n1 0 1 1\n1 1 1 1\n0 1 1 1\n"
         "4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 1 2 6 5\n4 2 3 7 6\n4 3 0 4 7\n";
}

const int kCubeFaces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4},
                              {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
const double kCubeVerts[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                 {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};

template <typename T>
void put(std::string& s, T v, bool big_endian = false) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if (big_endian) std::reverse(b, b + sizeof(T));
  s.append(b, sizeof(T));
}

std::string cube_ply_binary(bool big_endian) {
  std::string s = std::string("ply\nformat ") + (big_endian ? "binary_big_endian" : "binary_little_endian") +
                  " 1.0\nelement vertex 8\nproperty double x\nproperty double y\nproperty double z\n"
                  "element face 6\nproperty list uchar uint vertex_indices\nend_header\n";
  for (auto& v : kCubeVerts)
    for (double c : v) put(s, c, big_endian);
  for (auto& f : kCubeFaces) {
    put<std::uint8_t>(s, 4);
    for (int i : f) put<std::uint32_t>(s, static_cast<std::uint32_t>(i), big_endian);
  }
  return s;
}

// Cube as 12 triangles (fan of each quad).
std::vector<std::array<int, 3>> cube_triangles() {
  std::vector<std::array<int, 3>> t;
  for (auto& f : kCubeFaces) {
    t.push_back({f[0], f[1], f[2]});
    t.push_back({f[0], f[2], f[3]});
  }
  return t;
}

std::string cube_stl_ascii() {
  std::string s = "solid cube\n";
  for (auto& t : cube_triangles()) {
    s += "  facet normal 0 0 0\n    outer loop\n";
    for (int i : t)
      s += "      vertex " + std::to_string(kCubeVerts[i][0]) + " " + std::to_string(kCubeVerts[i][1]) + " " +
           std::to_string(kCubeVerts[i][2]) + "\n";
    s += "    endloop\n  endfacet\n";
  }
  return s + "endsolid cube\n";
}

std::string cube_stl_binary() {
  std::string s(80, ' ');
  std::memcpy(s.data(), "solid but actually binary", 25);  // binary STLs often start with "solid"
  const auto tris = cube_triangles();
  put<std::uint32_t>(s, static_cast<std::uint32_t>(tris.size()));
  for (auto& t : tris) {
    for (int k = 0; k < 3; ++k) put<float>(s, 0.0f);
    for (int i : t)
      for (double c : kCubeVerts[i]) put<float>(s, static_cast<float>(c));
    put<std::uint16_t>(s, 0);
  }
  return s;
}

void expect_unit_cube(const fs::Mesh& m, std::size_t faces) {
  ASSERT_EQ(m.vertices.size(), 8u);
  ASSERT_EQ(m.faces.size(), faces);
  EXPECT_EQ(fs::check_closed_manifold(m), "");
  EXPECT_NEAR(fs::mesh_signed_volume(m), 1.0, 1e-12);
}

std::string error_of(std::string_view bytes, fs::MeshFormat f) {
  try {
    fs::parse_mesh(bytes, f, "bad.mesh");
  } catch (const fs::Error& e) {
    return e.what();
  }
  return "(no error)";
}

std::filesystem::path temp_file(const std::string& name, const std::string& bytes) {
  const auto p =
      std::filesystem::temp_directory_path() / ("fs_mesh_io_test_" + std::to_string(::getpid()) + "_" + name);
  std::ofstream(p, std::ios::binary) << bytes;
  return p;
}

TEST(MeshIo, ReadsEveryFormatOfTheCube) {
  expect_unit_cube(fs::parse_mesh(kCubeOff, fs::MeshFormat::Off, "c.off"), 6);
  expect_unit_cube(fs::parse_mesh(kCubeObj, fs::MeshFormat::Obj, "c.obj"), 6);
  expect_unit_cube(fs::parse_mesh(cube_ply_ascii(), fs::MeshFormat::Ply, "c.ply"), 6);
  expect_unit_cube(fs::parse_mesh(cube_ply_binary(false), fs::MeshFormat::Ply, "c.ply"), 6);
  expect_unit_cube(fs::parse_mesh(cube_ply_binary(true), fs::MeshFormat::Ply, "c.ply"), 6);
  expect_unit_cube(fs::parse_mesh(cube_stl_ascii(), fs::MeshFormat::Stl, "c.stl"), 12);
  expect_unit_cube(fs::parse_mesh(cube_stl_binary(), fs::MeshFormat::Stl, "c.stl"), 12);
}

TEST(MeshIo, ReadMeshByExtensionNamesTheMeshByStem) {
  const auto p = temp_file("Box.OFF", kCubeOff);
  const fs::Mesh m = fs::read_mesh(p);
  std::filesystem::remove(p);
  EXPECT_EQ(m.name, p.stem().string());
  EXPECT_EQ(m.faces.size(), 6u);
  EXPECT_THROW(fs::read_mesh("/nonexistent/x.off"), fs::Error);
  EXPECT_THAT(
      [] {
        try {
          fs::read_mesh("x.step");
        } catch (const fs::Error& e) {
          return std::string(e.what());
        }
        return std::string();
      }(),
      HasSubstr("unknown mesh format"));
}

TEST(MeshIo, ReadsSharedPolyhedraAsClosedManifolds) {
  const auto dir = fs::test::shared_data() / "polyhedra/polyhedra-viewer/off";
  if (!std::filesystem::exists(dir)) GTEST_SKIP() << "no shared data";
  int n = 0;
  for (const char* name : {"cube", "square-cupola", "truncated-icosahedron", "snub-dodecahedron"}) {
    const fs::Mesh m = fs::read_mesh(dir / (std::string(name) + ".off"));
    EXPECT_EQ(fs::check_closed_manifold(m), "") << name;
    EXPECT_GT(std::abs(fs::mesh_signed_volume(m)), 0.1) << name;
    ++n;
  }
  EXPECT_EQ(n, 4);
}

TEST(MeshIo, OffErrorsNameTheLine) {
  using F = fs::MeshFormat;
  EXPECT_THAT(error_of("", F::Off), HasSubstr("bad.mesh: empty file"));
  EXPECT_THAT(error_of("OFF\n0 0 0\n", F::Off), HasSubstr("bad.mesh:2: mesh has no vertices"));
  EXPECT_THAT(error_of("OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n", F::Off),
              HasSubstr("bad.mesh:2: mesh has no faces"));
  EXPECT_THAT(error_of("OFF\n3 x 0\n", F::Off), HasSubstr("bad.mesh:2: bad face count 'x'"));
  EXPECT_THAT(error_of("OFF\n-3 1 0\n", F::Off), HasSubstr("bad vertex count"));
  EXPECT_THAT(error_of("OFF\n3000000000 1 0\n0 0 0\n", F::Off), HasSubstr("exceeds what the file can hold"));
  EXPECT_THAT(error_of("OFF\n3 1 0\n0 0 0\n1 0 0\n", F::Off),
              HasSubstr("bad.mesh:4: file ends after 2 of 3 vertices"));
  EXPECT_THAT(error_of("OFF\n3 1 0\n0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n", F::Off),
              HasSubstr("bad.mesh:4: vertex 1: non-finite"));
  EXPECT_THAT(error_of("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", F::Off),
              HasSubstr("bad.mesh:6: vertex index 3 out of range (3 vertices)"));
  EXPECT_THAT(error_of("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n", F::Off),
              HasSubstr("declares 4 vertices but lists 3"));
  EXPECT_THAT(error_of("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 1\n", F::Off),
              HasSubstr("face 0: face repeats vertex 1"));
  EXPECT_THAT(error_of("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n", F::Off), HasSubstr("need at least 3"));
  EXPECT_THAT(error_of("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", F::Off),
              HasSubstr("file ends after 1 of 2 faces"));
  // Counts on the header line and colours after faces are fine.
  EXPECT_EQ(fs::parse_mesh("OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2 255 0 0\n", F::Off, "x").faces.size(),
            1u);
}

TEST(MeshIo, ObjErrorsNameTheLine) {
  using F = fs::MeshFormat;
  EXPECT_THAT(error_of("# nothing\n", F::Obj), HasSubstr("bad.mesh: mesh has no vertices"));
  EXPECT_THAT(error_of("v 0 0 0\nv 1 0 0\nv 0 1 0\n", F::Obj), HasSubstr("mesh has no faces"));
  EXPECT_THAT(error_of("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", F::Obj),
              HasSubstr("bad.mesh:4: vertex index 4 out of range (3 vertices)"));
  EXPECT_THAT(error_of("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", F::Obj),
              HasSubstr("bad.mesh:4: bad vertex index '0'"));
  EXPECT_THAT(error_of("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 1 2\n", F::Obj),
              HasSubstr("bad.mesh:4: relative vertex index -4"));
  EXPECT_THAT(error_of("v 0 0 0\nv 1 inf 0\n", F::Obj), HasSubstr("bad.mesh:2: vertex 1: non-finite"));
  EXPECT_THAT(error_of("v 0 0\n", F::Obj), HasSubstr("bad.mesh:1: vertex needs 3 coordinates"));
  EXPECT_THAT(error_of("v 0 0 0\nv 1 0 0\nf 1 2\n", F::Obj), HasSubstr("bad.mesh:3: face has 2 vertices"));
}

TEST(MeshIo, StlErrorsNameLineOrOffset) {
  using F = fs::MeshFormat;
  std::string bin = cube_stl_binary();
  EXPECT_THAT(error_of(bin.substr(0, bin.size() - 7), F::Stl),
              HasSubstr("bad.mesh: at byte 80: binary STL declares 12 triangles"));
  std::string nan_bin = bin;
  const float nan = std::nanf("");
  std::memcpy(nan_bin.data() + 84 + 50 * 2 + 12 + 4, &nan, 4);
  EXPECT_THAT(error_of(nan_bin, F::Stl), HasSubstr("at byte 196: triangle 2: non-finite"));
  std::string empty(84, '\0');
  EXPECT_THAT(error_of(empty, F::Stl), HasSubstr("binary STL has no triangles"));
  EXPECT_THAT(error_of("garbage", F::Stl), HasSubstr("shorter than its 84-byte header"));
  EXPECT_THAT(error_of("solid x\nendsolid x\n", F::Stl), HasSubstr("ASCII STL has no facets"));
  EXPECT_THAT(
      error_of("solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0\nendloop\n", F::Stl),
      HasSubstr("bad.mesh:6: bad number 'endloop'"));
  EXPECT_THAT(error_of("solid x\nfacet normal 0 0 1\n outer loop\n", F::Stl),
              HasSubstr("file ends, expected 'vertex'"));
  const std::string ascii = cube_stl_ascii();
  EXPECT_THAT(error_of(ascii.substr(0, ascii.rfind("endsolid")), F::Stl), HasSubstr("without 'endsolid'"));
}

TEST(MeshIo, PlyErrorsNameLineOrOffset) {
  using F = fs::MeshFormat;
  EXPECT_THAT(error_of("plx\n", F::Ply), HasSubstr("bad.mesh:1: not a PLY file"));
  EXPECT_THAT(error_of("ply\nformat ascii 1.0\nelement vertex 1\n", F::Ply), HasSubstr("no 'end_header'"));
  EXPECT_THAT(error_of("ply\nformat weird 1.0\nend_header\n", F::Ply),
              HasSubstr("bad.mesh:2: unknown PLY format 'weird'"));
  EXPECT_THAT(error_of("ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n", F::Ply),
              HasSubstr("bad.mesh:4: unknown property type 'quad'"));
  std::string ascii = cube_ply_ascii();
  std::string bad = ascii;
  bad.replace(bad.find("4 3 0 4 7"), 9, "4 3 0 4 8");
  EXPECT_THAT(error_of(bad, F::Ply),
              HasSubstr("bad.mesh:25: face 5: vertex index 8 out of range (8 vertices)"));
  bad = ascii;
  bad.replace(bad.find("1 1 1 1\n"), 8, "1 nan 1 1\n");
  EXPECT_THAT(error_of(bad, F::Ply), HasSubstr("bad.mesh:18: vertex 6: non-finite"));
  EXPECT_THAT(error_of(ascii.substr(0, ascii.size() - 6), F::Ply),
              HasSubstr("bad.mesh:25: file ends inside the PLY data"));
  bad = ascii;
  bad.replace(bad.find("element vertex 8"), 16, "element vertex 99999999999");
  EXPECT_THAT(error_of(bad, F::Ply), HasSubstr("exceeds what the file can hold"));
  std::string bin = cube_ply_binary(false);
  const std::size_t header = bin.find("end_header\n") + 11;
  EXPECT_THAT(error_of(bin.substr(0, bin.size() - 3), F::Ply),
              HasSubstr("at byte " + std::to_string(bin.size() - 3 - 1)));
  std::string big_index = bin;
  // First face, first index (after the 8 * 24 vertex bytes and the list count byte) -> 1000.
  const std::uint32_t thousand = 1000;
  std::memcpy(big_index.data() + header + 8 * 24 + 1, &thousand, 4);
  EXPECT_THAT(error_of(big_index, F::Ply), HasSubstr("face 0: vertex index 1000 out of range"));
  EXPECT_THAT(
      error_of(
          "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
          "element face 0\nproperty list uchar int vertex_indices\nend_header\n",
          F::Ply),
      HasSubstr("mesh has no vertices"));
}

TEST(MeshIo, ManifoldCheckFindsOpenAndFlippedMeshes) {
  fs::Mesh m = fs::parse_mesh(kCubeOff, fs::MeshFormat::Off, "c.off");
  fs::Mesh open = m;
  open.faces.pop_back();
  EXPECT_THAT(fs::check_closed_manifold(open), HasSubstr("not closed"));
  fs::Mesh flipped = m;
  std::reverse(flipped.faces[0].begin(), flipped.faces[0].end());
  EXPECT_THAT(fs::check_closed_manifold(flipped), HasSubstr("same direction"));
  fs::Mesh inverted = m;
  for (auto& f : inverted.faces) std::reverse(f.begin(), f.end());
  EXPECT_EQ(fs::check_closed_manifold(inverted), "");
  EXPECT_NEAR(fs::mesh_signed_volume(inverted), -1.0, 1e-12);
}

}  // namespace
