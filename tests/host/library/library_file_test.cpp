// .fslib round trip and rejection of bad files.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "common/error.hpp"
#include "common/mesh.hpp"
#include "host/library/library.hpp"
#include "host/library/polycubes.hpp"
#include "support/test_paths.hpp"

namespace {

using namespace fs::host;

Library small_library() {
  Library lib;
  const auto dir = fs::test::shared_data() / "polyhedra/polyhedra-viewer/off";
  for (const char* n : {"cube", "tetrahedron", "square-pyramid"})
    lib.add(build_model(fs::read_mesh(dir / (std::string(n) + ".off"))));
  lib.add(polycube_model({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {1, 1, 0}}, 20, "T"));
  fs::host::Polycube ring;
  for (int x = 0; x < 3; ++x)
    for (int y = 0; y < 3; ++y)
      if (x != 1 || y != 1) ring.push_back({x, y, 0});
  lib.add(polycube_model(ring, 20, "ring"));
  return lib;
}

void expect_same(const Model& a, const Model& b) {
  EXPECT_EQ(a.name, b.name);
  ASSERT_EQ(a.face_count(), b.face_count());
  for (std::size_t i = 0; i < a.face_count(); ++i) {
    EXPECT_EQ(a.faces[i].normal, b.faces[i].normal);
    EXPECT_EQ(a.faces[i].area, b.faces[i].area);
    EXPECT_EQ(a.faces[i].centroid, b.faces[i].centroid);
    EXPECT_EQ(a.faces[i].loops, b.faces[i].loops);
    EXPECT_NEAR(a.faces[i].perimeter, b.faces[i].perimeter, 1e-9);
  }
  ASSERT_EQ(a.arc_count(), b.arc_count());
  for (std::size_t i = 0; i < a.arc_count(); ++i) {
    EXPECT_EQ(a.graph.arcs[i].a, b.graph.arcs[i].a);
    EXPECT_EQ(a.graph.arcs[i].b, b.graph.arcs[i].b);
    EXPECT_EQ(a.graph.arcs[i].border, b.graph.arcs[i].border);
  }
  EXPECT_EQ(a.symmetries, b.symmetries);
  EXPECT_NEAR(a.total_area, b.total_area, 1e-9);
  EXPECT_NEAR(a.volume, b.volume, 1e-9);
  EXPECT_TRUE(a.center.isApprox(b.center, 1e-12) || (a.center - b.center).norm() < 1e-12);
  EXPECT_NEAR(a.bounding_radius, b.bounding_radius, 1e-12);
  ASSERT_EQ(a.graph.nodes.size(), b.graph.nodes.size());
}

TEST(LibraryFile, RoundTripInMemoryAndOnDisk) {
  const Library lib = small_library();
  const auto bytes = lib.to_bytes();
  const Library back = Library::from_bytes(bytes, "mem");
  ASSERT_EQ(back.models.size(), lib.models.size());
  for (std::size_t i = 0; i < lib.models.size(); ++i) expect_same(lib.models[i], back.models[i]);
  EXPECT_EQ(back.to_bytes(), bytes);

  const auto path = std::filesystem::temp_directory_path() / "fs_library_test.fslib";
  lib.save(path);
  const Library disk = Library::load(path);
  std::filesystem::remove(path);
  ASSERT_EQ(disk.models.size(), lib.models.size());
  ASSERT_NE(disk.find("ring"), nullptr);
  std::size_t holed = 0;
  for (const auto& f : disk.find("ring")->faces) holed += f.loops.size() == 2;
  EXPECT_EQ(holed, 2u);
  EXPECT_EQ(disk.find("nothing"), nullptr);
  EXPECT_EQ(disk.find("cube")->symmetry_order(), 24u);
}

TEST(LibraryFile, DuplicateNamesRejected) {
  Library lib = small_library();
  EXPECT_THROW(lib.add(lib.models[0]), fs::Error);
}

std::string error_of(const std::vector<std::uint8_t>& bytes) {
  try {
    Library::from_bytes(bytes, "bad.fslib");
  } catch (const fs::Error& e) {
    return e.what();
  }
  return "";
}

TEST(LibraryFile, EveryTruncationIsAnError) {
  Library lib;
  lib.add(polycube_model({{0, 0, 0}}, 1, "c"));
  const auto bytes = lib.to_bytes();
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    const std::string e =
        error_of(std::vector<std::uint8_t>(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(n)));
    EXPECT_NE(e.find("bad.fslib: at byte"), std::string::npos) << n << ": " << e;
  }
}

TEST(LibraryFile, CorruptionIsReportedWithOffsets) {
  const auto good = small_library().to_bytes();
  auto magic = good;
  magic[0] = 'X';
  EXPECT_NE(error_of(magic).find("bad magic"), std::string::npos);
  auto version = good;
  version[8] = 7;
  EXPECT_NE(error_of(version).find("at byte 8: unsupported .fslib version 7"), std::string::npos)
      << error_of(version);
  auto flipped = good;
  flipped[good.size() / 2] ^= 0x40;
  EXPECT_NE(error_of(flipped).find("CRC mismatch"), std::string::npos);
  auto longer = good;
  longer.push_back(0);
  EXPECT_NE(error_of(longer).find("payload size"), std::string::npos);
  // A structurally bad payload with a valid CRC: arc to a face that does not exist.
  Library one;
  one.add(polycube_model({{0, 0, 0}}, 1, "c"));
  one.models[0].graph.arcs[0].b = 40;
  const std::string e = error_of(one.to_bytes());
  EXPECT_NE(e.find("does not join two faces of 6"), std::string::npos) << e;
  Library nosym;
  nosym.add(polycube_model({{0, 0, 0}}, 1, "c"));
  nosym.models[0].symmetries[1](0, 0) = 3;
  EXPECT_NE(error_of(nosym.to_bytes()).find("not a rotation"), std::string::npos);
  EXPECT_THROW(Library::load("/nonexistent/dir/x.fslib"), fs::Error);
}

}  // namespace
