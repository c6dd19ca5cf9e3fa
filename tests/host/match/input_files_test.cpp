// Match parameters (`--params FILE`) and PFRG JSON files: devices and links to them are refused (a preset
// name is still a preset), files above the cap are refused unread.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "common/error.hpp"
#include "common/input_file.hpp"
#include "host/match/params.hpp"
#include "host/pfrg/pfrg.hpp"
#include "support/error_of.hpp"

namespace {

using fs::test::error_of;
namespace stdfs = std::filesystem;

stdfs::path tmp_dir(const std::string& tag) {
  const auto d = stdfs::temp_directory_path() / ("fs_match_inputs_" + tag + "_" + std::to_string(::getpid()));
  stdfs::remove_all(d);
  stdfs::create_directories(d);
  return d;
}

TEST(MatchInputs, ParamsFromADeviceOrALinkToOneAreRefused) {
  EXPECT_EQ(error_of([] { fs::host::match::read_params("/dev/zero"); }),
            "/dev/zero: not a regular file (character device)");
  const auto dir = tmp_dir("dev");
  stdfs::create_symlink("/dev/zero", dir / "p.json");
  stdfs::create_symlink("/dev/zero", dir / "g.json");
  EXPECT_EQ(error_of([&] { fs::host::match::read_params((dir / "p.json").string()); }),
            (dir / "p.json").string() + ": not a regular file (character device)");
  EXPECT_EQ(error_of([&] { fs::host::read_pfrg_json(dir / "g.json"); }),
            (dir / "g.json").string() + ": not a regular file (character device)");
  EXPECT_EQ(fs::host::match::read_params("fast").name, "fast");  // presets are unaffected
  stdfs::remove_all(dir);
}

TEST(MatchInputs, ParamsAndGraphsAboveTheCapAreRefused) {
  const auto dir = tmp_dir("cap");
  const auto sparse = [&](const char* name, std::uint64_t size) {
    const auto p = dir / name;
    const int fd = ::open(p.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    EXPECT_GE(fd, 0);
    EXPECT_EQ(::ftruncate(fd, static_cast<off_t>(size)), 0);
    ::close(fd);
    return p;
  };
  const auto p = sparse("p.json", fs::kMaxConfigFileBytes + 1);
  EXPECT_EQ(error_of([&] { fs::host::match::read_params(p.string()); }),
            p.string() + ": 1.0 MB, more than the 1 MiB a match parameter file may have");
  const auto g = sparse("g.json", fs::kMaxGraphFileBytes + 1);
  EXPECT_EQ(error_of([&] { fs::host::read_pfrg_json(g); }),
            g.string() + ": 67.1 MB, more than the 64 MiB a PFRG JSON file may have");
  stdfs::remove_all(dir);
}

}  // namespace
