// What a library is read from: a .fslib that is a link to a device, one above the cap, a library without
// models, and mesh files whose errors name the whole path (not the stem the model is named by).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "common/error.hpp"
#include "common/input_file.hpp"
#include "host/library/library.hpp"
#include "host/library/mesh_files.hpp"
#include "support/error_of.hpp"

namespace {

using namespace fs::host;
using fs::test::error_of;
namespace stdfs = std::filesystem;

stdfs::path tmp_dir(const std::string& tag) {
  const auto d = stdfs::temp_directory_path() / ("fs_lib_inputs_" + tag + "_" + std::to_string(::getpid()));
  stdfs::remove_all(d);
  stdfs::create_directories(d);
  return d;
}

// A closed, outward-wound tetrahedron (20 mm edges along the axes).
constexpr const char* kTetraOff =
    "OFF\n4 4 0\n0 0 0\n20 0 0\n0 20 0\n0 0 20\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
constexpr const char* kTetraObj =
    "v 0 0 0\nv 20 0 0\nv 0 20 0\nv 0 0 20\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

void write_text(const stdfs::path& p, const std::string& s) { std::ofstream(p, std::ios::binary) << s; }

TEST(LibraryInputs, LinkToADeviceIsRefused) {
  const auto dir = tmp_dir("dev");
  const auto link = dir / "zero.fslib";
  stdfs::create_symlink("/dev/zero", link);
  const std::string expected = link.string() + ": not a regular file (character device)";
  EXPECT_EQ(error_of([&] { Library::load(link); }), expected);
  EXPECT_EQ(error_of([&] { load_or_build_library({link.string()}); }), expected);
  stdfs::remove_all(dir);
}

TEST(LibraryInputs, FileAboveTheCapIsRefusedUnread) {
  const auto dir = tmp_dir("cap");
  const auto p = dir / "huge.fslib";
  const int fd = ::open(p.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::ftruncate(fd, static_cast<off_t>(fs::kMaxLibraryFileBytes + 1)), 0);
  ::close(fd);
  EXPECT_EQ(error_of([&] { Library::load(p); }),
            p.string() + ": 1.1 GB, more than the 1 GiB a model library may have");
  stdfs::remove_all(dir);
}

TEST(LibraryInputs, ALibraryWithoutModelsNamesTheInput) {
  const auto dir = tmp_dir("empty");
  const auto p = dir / "empty.fslib";
  Library{}.save(p);
  EXPECT_EQ(Library::load(p).models.size(), 0u);  // a valid file: `library list` shows it
  EXPECT_EQ(error_of([&] { load_or_build_library({p.string()}); }),
            p.string() + ": the library has no models");
  stdfs::remove_all(dir);
}

TEST(LibraryInputs, MeshErrorsNameTheWholePath) {
  const auto dir = tmp_dir("mesh");
  stdfs::create_directories(dir / "a");
  write_text(dir / "a" / "flat.off", "OFF\n3 1 0\n0 0 0\n20 0 0\n0 20 0\n3 0 1 2\n");
  const std::string e = error_of([&] { load_or_build_library({(dir / "a").string()}); });
  EXPECT_EQ(e.rfind((dir / "a" / "flat.off").string() + ": ", 0), 0u) << e;
  EXPECT_NE(e.find("non-degenerate facets"), std::string::npos) << e;

  // Two files with one stem: the second is named in full.
  stdfs::remove(dir / "a" / "flat.off");
  write_text(dir / "a" / "tetra.obj", kTetraObj);
  write_text(dir / "a" / "tetra.off", kTetraOff);
  EXPECT_EQ(load_or_build_library({(dir / "a" / "tetra.off").string()}).models.at(0).name, "tetra");
  EXPECT_EQ(error_of([&] { load_or_build_library({(dir / "a").string()}); }),
            (dir / "a" / "tetra.off").string() +
                ": a model named 'tetra' is already in the library (names are file stems)");
  stdfs::remove_all(dir);
}

}  // namespace
