// .fslib round trip and rejection of bad files.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <zlib.h>

#include "common/error.hpp"
#include "common/mesh.hpp"
#include "host/library/library.hpp"
#include "host/library/polycubes.hpp"
#include "support/same_arc_index.hpp"
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
  // The same pair of faces twice (reversed), named at the second: header 28, name "c" 5, open flag 1, face
  // count 4, six square faces of 64 + 4 + 4 + 4 x 24 bytes, arc count 4, then 16 bytes per arc.
  Library dup;
  dup.add(polycube_model({{0, 0, 0}}, 1, "c"));
  auto& arcs = dup.models[0].graph.arcs;
  arcs[4] = PfrgArc{arcs[1].b, arcs[1].a, arcs[1].border};
  const std::size_t arcs_at = 28 + 5 + 1 + 4 + 6 * (64 + 4 + 4 + 4 * 24) + 4;
  EXPECT_EQ(error_of(dup.to_bytes()), fmt::format("bad.fslib: at byte {}: duplicate arc ({}, {})",
                                                  arcs_at + 4 * 16, arcs[1].b, arcs[1].a));
  Library nosym;
  nosym.add(polycube_model({{0, 0, 0}}, 1, "c"));
  nosym.models[0].symmetries[1](0, 0) = 3;
  EXPECT_NE(error_of(nosym.to_bytes()).find("not a rotation"), std::string::npos);
  EXPECT_THROW(Library::load("/nonexistent/dir/x.fslib"), fs::Error);
}

// Bytes as a version 1 file held them: no arc index after the models.
std::vector<std::uint8_t> as_version_1(const Library& lib) {
  auto bytes = lib.to_bytes();
  const auto& ix = lib.index;
  const std::size_t tail = 4 + 16 * ix.entry_array().size() + 4 + 24 * ix.path_array().size() +
                           4 * (ix.references() + 1) + 8 * ix.references();
  bytes.resize(bytes.size() - tail);
  auto put32 = [&](std::size_t at, std::uint32_t v) {
    for (int i = 0; i < 4; ++i)
      bytes[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v >> (8 * i));
  };
  put32(8, 1);
  const std::uint64_t payload = bytes.size() - 28;
  put32(16, static_cast<std::uint32_t>(payload));
  put32(20, static_cast<std::uint32_t>(payload >> 32));
  put32(24, static_cast<std::uint32_t>(crc32(0, bytes.data() + 28, static_cast<uInt>(payload))));
  return bytes;
}

// The payload CRC made right again after an edit (a structurally bad file that is not corrupt).
std::vector<std::uint8_t> with_crc(std::vector<std::uint8_t> bytes) {
  const auto c =
      static_cast<std::uint32_t>(crc32(0, bytes.data() + 28, static_cast<uInt>(bytes.size() - 28)));
  for (int i = 0; i < 4; ++i)
    bytes[24 + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(c >> (8 * i));
  return bytes;
}

std::vector<const Pfrg*> graphs(const Library& lib) {
  std::vector<const Pfrg*> g;
  for (const auto& m : lib.models) g.push_back(&m.graph);
  return g;
}

TEST(LibraryFile, TheArcIndexIsStoredAndReadBack) {
  Library lib = small_library();
  EXPECT_FALSE(lib.index_describes_models());                       // models added, no index built
  const Library back = Library::from_bytes(lib.to_bytes(), "mem");  // to_bytes builds it for the file
  ASSERT_TRUE(back.index_describes_models());
  fs::test::expect_same_index(back.index, match::ArcIndex(graphs(back)));
  lib.build_index();
  EXPECT_TRUE(lib.index_describes_models());
  EXPECT_EQ(lib.to_bytes(), back.to_bytes());
  // A model replaced by one of the same faces and arcs at another size: the index no longer describes it.
  Library resized = back;
  resized.models[3] = polycube_model({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {1, 1, 0}}, 30, "T");
  EXPECT_FALSE(resized.index_describes_models());
  // A model added later: the index no longer describes the library.
  Library more = back;
  more.add(polycube_model({{0, 0, 0}, {0, 0, 1}}, 20, "pair"));
  EXPECT_FALSE(more.index_describes_models());
  EXPECT_TRUE(Library::from_bytes(more.to_bytes(), "mem").index_describes_models());
}

TEST(LibraryFile, VersionOneFilesAreStillRead) {
  Library lib = small_library();
  lib.build_index();
  const Library v1 = Library::from_bytes(as_version_1(lib), "v1.fslib");
  ASSERT_EQ(v1.models.size(), lib.models.size());
  for (std::size_t i = 0; i < lib.models.size(); ++i) expect_same(lib.models[i], v1.models[i]);
  EXPECT_EQ(v1.index.references(), 0u);
  EXPECT_FALSE(v1.index_describes_models());
  EXPECT_EQ(v1.to_bytes(), lib.to_bytes());  // written again as the current version, with the index
}

// A version 2 file's index holds face areas alone, without the shallow folds the matcher's area condition now
// counts (match::kAreaFoldMaxDeg): it is checked, then dropped, so that the recognizer builds the index
// again.
TEST(LibraryFile, VersionTwoFilesAreReadAndTheirIndexBuiltAgain) {
  Library lib = small_library();
  lib.build_index();
  auto bytes = lib.to_bytes();
  ASSERT_EQ(bytes[8], fs::host::kFslibVersion);
  bytes[8] = 2;  // the header's version (the CRC covers the payload only)
  const Library v2 = Library::from_bytes(bytes, "v2.fslib");
  ASSERT_EQ(v2.models.size(), lib.models.size());
  for (std::size_t i = 0; i < lib.models.size(); ++i) expect_same(lib.models[i], v2.models[i]);
  EXPECT_EQ(v2.index.references(), 0u);
  EXPECT_EQ(v2.to_bytes(), lib.to_bytes());
  // Its index is still checked: a bad one is reported as in a version 3 file.
  bytes[bytes.size() - 1] ^= 0x40;  // the last model's fingerprint
  EXPECT_NE(error_of(with_crc(bytes)).find("fingerprints differ"), std::string::npos)
      << error_of(with_crc(bytes));
  bytes[8] = 4;
  EXPECT_NE(error_of(with_crc(bytes)).find("unsupported .fslib version 4 (this build reads 1 to 3)"),
            std::string::npos);
}

TEST(LibraryFile, ABadArcIndexIsReportedWithItsOffset) {
  Library lib = small_library();
  lib.build_index();
  const auto good = lib.to_bytes();
  const std::size_t index_at = as_version_1(lib).size();
  const std::size_t refs = lib.models.size();
  // The first entry's reference out of range (its u32 after three f32).
  auto ref = good;
  ref[index_at + 4 + 12] = 0xFF;
  std::string e = error_of(with_crc(ref));
  EXPECT_NE(e.find(fmt::format("bad.fslib: at byte {}: arc index: entry 0", index_at)), std::string::npos)
      << e;
  // An angle that is not a number.
  auto nan = good;
  for (int i = 0; i < 4; ++i) nan[index_at + 4 + static_cast<std::size_t>(i)] = 0xFF;
  e = error_of(with_crc(nan));
  EXPECT_NE(e.find("arc index entry angle is not a finite number"), std::string::npos) << e;
  // Arc counts of other models (the last u32 of the file).
  auto counts = good;
  counts[counts.size() - 4] ^= 1;
  e = error_of(with_crc(counts));
  EXPECT_NE(e.find("the arc index does not describe the models"), std::string::npos) << e;
  // A middle path start past the paths (the ends are right).
  auto middle = good;
  const std::size_t second_start = good.size() - 8 * refs - 4 * (refs + 1) + 4;
  for (int i = 0; i < 4; ++i) middle[second_start + static_cast<std::size_t>(i)] = 0xFF;
  e = error_of(with_crc(middle));
  EXPECT_NE(e.find("arc index: path start 4294967295 of reference 1 is not between"), std::string::npos) << e;
  // Path starts that run past the paths.
  auto starts = good;
  const std::size_t last_start = good.size() - 8 * refs - 4;
  starts[last_start] += 1;
  e = error_of(with_crc(starts));
  EXPECT_NE(e.find("arc index: path starts run from 0 to"), std::string::npos) << e;
}

}  // namespace
