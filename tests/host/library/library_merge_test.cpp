// Libraries that combine (issue #24): several .fslib files and meshes / directories in one library, in the
// order of the inputs; a model name given twice names both sources; a merged .fslib equals loading its parts.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "common/error.hpp"
#include "host/library/library.hpp"
#include "host/library/library_merge.hpp"
#include "host/library/mesh_files.hpp"
#include "host/library/polycubes.hpp"
#include "support/error_of.hpp"
#include "support/same_arc_index.hpp"
#include "support/test_paths.hpp"

namespace {

using namespace fs::host;
using fs::test::error_of;
namespace stdfs = std::filesystem;

stdfs::path meshes() { return fs::test::source_dir() / "hw-sim/scenes/meshes"; }
std::string mesh(const char* name) { return (meshes() / (std::string(name) + ".off")).string(); }

struct TempDir {
  stdfs::path path;
  explicit TempDir(const std::string& tag)
      : path(stdfs::temp_directory_path() / ("fs_lib_merge_" + tag + "_" + std::to_string(::getpid()))) {
    stdfs::remove_all(path);
    stdfs::create_directories(path);
  }
  ~TempDir() { stdfs::remove_all(path); }
  std::string operator/(const std::string& name) const { return (path / name).string(); }
};

std::vector<std::string> names(const Library& lib) {
  std::vector<std::string> out;
  for (const auto& m : lib.models) out.push_back(m.name);
  return out;
}

// a.fslib: cube, wedge (built from meshes); b.fslib: two polycubes.
struct Parts {
  TempDir dir{"parts"};
  std::string a = dir / "a.fslib", b = dir / "b.fslib";
  Parts() {
    load_or_build_library({mesh("cube"), mesh("wedge")}).save(a);
    Library cubes;
    cubes.add(polycube_model({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, 20, polycube_name(3, 1)));
    cubes.add(polycube_model({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}, 20, polycube_name(3, 2)));
    cubes.save(b);
  }
};

TEST(LibraryMerge, SeveralLibrariesAndMeshesInTheOrderOfTheInputs) {
  const Parts p;
  // .fslib, .fslib: the models of each file in file order.
  EXPECT_EQ(names(load_or_build_library({p.a, p.b})),
            (std::vector<std::string>{"cube", "wedge", "polycube-3-001", "polycube-3-002"}));
  EXPECT_EQ(names(load_or_build_library({p.b, p.a})),
            (std::vector<std::string>{"polycube-3-001", "polycube-3-002", "cube", "wedge"}));
  // A mesh, a library, a directory of two meshes (sorted), a library.
  const TempDir d("mixed");
  stdfs::create_directories(d.path / "more");
  for (const char* n : {"hex_prism", "box"})
    stdfs::copy_file(mesh(n), d.path / "more" / (std::string(n) + ".off"));
  const Library mixed = load_or_build_library({mesh("corner"), p.a, d / "more", p.b});
  EXPECT_EQ(names(mixed), (std::vector<std::string>{"corner", "cube", "wedge", "box", "hex_prism",
                                                    "polycube-3-001", "polycube-3-002"}));
  // The models are the files' models: the same bytes as each part on its own.
  Library a_part;
  a_part.models = {mixed.models[1], mixed.models[2]};
  EXPECT_EQ(a_part.to_bytes(), Library::load(p.a).to_bytes());
  // Each model remembers its source.
  const LibraryMerge g = gather_library({mesh("corner"), p.a, d / "more", p.b});
  EXPECT_EQ(g.source_of(0), mesh("corner"));
  EXPECT_EQ(g.source_of(1), p.a);
  EXPECT_EQ(g.source_of(2), p.a);
  EXPECT_EQ(g.source_of(3), d / "more/box.off");
  EXPECT_EQ(g.source_of(6), p.b);
  ASSERT_NE(g.source_of("wedge"), nullptr);
  EXPECT_EQ(*g.source_of("wedge"), p.a);
  EXPECT_EQ(g.source_of("nothing"), nullptr);
}

TEST(LibraryMerge, TheMergedLibraryCarriesTheIndexOfAllItsModels) {
  const Parts p;
  // Stored indexes (a, b) and models built from meshes (corner, box) before, between and after them.
  const Library mixed = load_or_build_library({mesh("corner"), p.a, mesh("box"), p.b, mesh("hex_prism")});
  ASSERT_EQ(mixed.models.size(), 7u);
  ASSERT_TRUE(mixed.index_describes_models());
  std::vector<const Pfrg*> graphs;
  for (const auto& m : mixed.models) graphs.push_back(&m.graph);
  fs::test::expect_same_index(mixed.index, match::ArcIndex(graphs));
  Library fresh;  // the same models indexed at once: the same file, byte for byte
  fresh.models = mixed.models;
  fresh.build_index();
  EXPECT_EQ(fresh.to_bytes(), mixed.to_bytes());
  // Libraries only; a single library keeps its stored index.
  const Library two = load_or_build_library({p.b, p.a});
  ASSERT_TRUE(two.index_describes_models());
  const Library one = load_or_build_library({p.a});
  fs::test::expect_same_index(one.index, Library::load(p.a).index);
}

TEST(LibraryMerge, ExtensionIsCaseInsensitive) {
  const Parts p;
  const std::string upper = p.dir / "A.FSLIB";
  stdfs::copy_file(p.a, upper);
  EXPECT_EQ(names(load_or_build_library({upper, p.b})).size(), 4u);
}

TEST(LibraryMerge, DuplicateNamesNameBothSources) {
  const Parts p;
  // Library and library.
  const std::string a2 = p.dir / "a2.fslib";
  stdfs::copy_file(p.a, a2);
  EXPECT_EQ(error_of([&] {
              load_or_build_library({p.a, a2});
            }),
            a2 + ": a model named 'cube' is already in the library (from " + p.a + ")");
  // Mesh after a library, library after a mesh.
  EXPECT_EQ(error_of([&] {
              load_or_build_library({p.a, mesh("wedge")});
            }),
            mesh("wedge") + ": a model named 'wedge' is already in the library (from " + p.a + ")");
  EXPECT_EQ(error_of([&] {
              load_or_build_library({mesh("wedge"), p.a});
            }),
            p.a + ": a model named 'wedge' is already in the library (from " + mesh("wedge") + ")");
  // Meshes of two directories with one stem.
  const TempDir d("dup");
  stdfs::create_directories(d.path / "x");
  stdfs::copy_file(mesh("cube"), d.path / "x" / "cube.off");
  EXPECT_EQ(error_of([&] {
              load_or_build_library({meshes().string(), d / "x"});
            }),
            d / "x/cube.off" + ": a model named 'cube' is already in the library (from " + mesh("cube") +
                "; names are file stems)");
  // The merge keeps nothing of a failed add.
  LibraryMerge m;
  m.add_all(Library::load(p.a), p.a);
  EXPECT_EQ(error_of([&] { m.add(Library::load(p.a).models[1], "again.fslib"); }),
            "again.fslib: a model named 'wedge' is already in the library (from " + p.a + ")");
  EXPECT_EQ(m.size(), 2u);
}

TEST(LibraryMerge, AnInputNamedTwiceOrOfNoKnownKindIsRefusedBeforeLoading) {
  const Parts p;
  EXPECT_EQ(error_of([&] {
              load_or_build_library({p.a, p.b, p.a});
            }),
            p.a + ": named twice among the library inputs");
  const std::string other = (p.dir.path / "." / "a.fslib").string();
  EXPECT_EQ(error_of([&] {
              load_or_build_library({p.a, other});
            }),
            other + ": named twice among the library inputs (also as " + p.a + ")");
  const std::string txt = p.dir / "notes.txt";
  std::ofstream(txt) << "hello\n";
  EXPECT_EQ(error_of([&] {
              load_or_build_library({p.a, txt});
            }),
            txt +
                ": neither a model library (.fslib) nor a mesh (.off, .obj, .stl, .ply) nor a directory of "
                "meshes");
  EXPECT_EQ(error_of([&] {
              load_or_build_library({p.a, p.dir / "missing.fslib"});
            }),
            p.dir / "missing.fslib" + ": no such file or directory");
  // A broken library among several is named by its own errors.
  const std::string bad = p.dir / "bad.fslib";
  std::ofstream(bad, std::ios::binary) << "not a library";
  const std::string e = error_of([&] { load_or_build_library({p.a, bad}); });
  EXPECT_EQ(e.rfind(bad + ": ", 0), 0u) << e;
}

TEST(LibraryMerge, AnEmptyLibraryIsFineAmongOthersButNotAlone) {
  const Parts p;
  const std::string empty = p.dir / "empty.fslib";
  Library{}.save(empty);
  EXPECT_EQ(load_or_build_library({empty, p.b}).models.size(), 2u);
  EXPECT_EQ(error_of([&] { load_or_build_library({empty}); }), empty + ": the library has no models");
}

TEST(LibraryMerge, MergedFileEqualsLoadingTheParts) {
  const Parts p;
  const std::string merged = p.dir / "merged.fslib";
  gather_library({p.a, p.b, mesh("hex_prism")}).release().save(merged);
  const Library whole = Library::load(merged);
  const Library parts = load_or_build_library({p.a, p.b, mesh("hex_prism")});
  EXPECT_EQ(whole.to_bytes(), parts.to_bytes());
  EXPECT_EQ(names(whole),
            (std::vector<std::string>{"cube", "wedge", "polycube-3-001", "polycube-3-002", "hex_prism"}));
  // Byte for byte, each part's models are in the merged file.
  const Library a = Library::load(p.a), b = Library::load(p.b);
  Library concatenated;
  for (const auto* part : {&a, &b})
    for (const auto& m : part->models) concatenated.models.push_back(m);
  concatenated.models.push_back(whole.models.back());
  EXPECT_EQ(concatenated.to_bytes(), whole.to_bytes());
  // Merging the merged file with nothing new is the same file.
  EXPECT_EQ(load_or_build_library({merged}).to_bytes(), whole.to_bytes());
}

}  // namespace
