// End-to-end: libraries that combine (issue #24), through the built `facetscan` as a user runs it:
// `library merge` of .fslib files and meshes, `-l` given several .fslib files and meshes (demo, recognize),
// and the errors of a model name given twice or an input named twice.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "support/run_command.hpp"
#include "support/test_paths.hpp"

namespace {

namespace stdfs = std::filesystem;

using fs::test::CmdResult;
using fs::test::run;

std::string facetscan() { return (fs::test::bin_dir() / "facetscan").string(); }
std::string mesh(const std::string& name) {
  return (fs::test::source_dir() / "hw-sim/scenes/meshes" / (name + ".off")).string();
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

struct Dir {
  stdfs::path path = stdfs::temp_directory_path() / ("facetscan-e2e-merge-" + std::to_string(getpid()));
  Dir() {
    stdfs::remove_all(path);
    stdfs::create_directories(path);
  }
  ~Dir() { stdfs::remove_all(path); }
  std::string operator/(const std::string& name) const { return (path / name).string(); }
};

// The models of a recognition JSON.
std::vector<std::string> models_of(const stdfs::path& json) {
  std::ifstream f(json);
  std::vector<std::string> out;
  if (!f) return out;
  const nlohmann::json j = nlohmann::json::parse(f);
  for (const auto& o : j["objects"]) out.push_back(o["model"].get<std::string>());
  return out;
}

TEST(EndToEndLibraries, MergeAndSeveralLibrariesOnTheCommandLine) {
  const Dir d;
  const std::string a = d / "a.fslib", b = d / "b.fslib", merged = d / "merged.fslib";
  CmdResult r =
      run(facetscan() + " library build " + mesh("cube") + " " + mesh("wedge") + " -o " + a + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  r = run(facetscan() + " library polycubes --max-volume 3 -o " + b + " -q");
  ASSERT_EQ(r.code, 0) << r.out;

  // merge: two libraries and a mesh, in that order.
  r = run(facetscan() + " library merge " + a + " " + b + " " + mesh("hex_prism") + " -o " + merged);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(
      contains(r.out, a + ": 2 models\n" + b + ": 4 models\nmeshes: 1 models\nwrote 7 models to " + merged))
      << r.out;
  r = run(facetscan() + " library list " + merged);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(contains(r.out, "\n7 models")) << r.out;
  EXPECT_LT(r.out.find("cube"), r.out.find("polycube-1-001")) << r.out;
  EXPECT_LT(r.out.find("polycube-3-002"), r.out.find("hex_prism")) << r.out;

  // A model name twice: both sources named, nothing written.
  r = run(facetscan() + " library merge " + merged + " " + mesh("wedge") + " -o " + (d / "dup.fslib"));
  EXPECT_NE(r.code, 0);
  EXPECT_TRUE(contains(r.out, "facetscan: error: " + mesh("wedge") +
                                  ": a model named 'wedge' is already in the library (from " + merged + ")"))
      << r.out;
  EXPECT_FALSE(stdfs::exists(d / "dup.fslib"));

  // The demo scans the pyramid and recognizes it with -l given two libraries and a mesh.
  r = run(facetscan() + " demo --scene pyramid --galvo gpio -q -l " + a + " -l " + b + " -l " +
          mesh("truncated_pyramid") + " -o " + (d / "demo"));
  ASSERT_EQ(r.code, 0) << r.out;
  const stdfs::path scan = d.path / "demo" / "scan.fscan";
  ASSERT_TRUE(stdfs::exists(scan)) << r.out;

  // recognize: the merged library plus a mesh; the same as the parts.
  for (const std::string& libs :
       {" -l " + merged + " -l " + mesh("truncated_pyramid"),
        " -l " + a + " " + b + " " + mesh("hex_prism") + " " + mesh("truncated_pyramid")}) {
    r = run(facetscan() + " recognize " + scan.string() + libs + " -q --json " + (d / "r.json"));
    ASSERT_EQ(r.code, 0) << libs << "\n" << r.out;
    EXPECT_EQ(models_of(d.path / "r.json"), std::vector<std::string>{"truncated_pyramid"}) << libs;
  }
  // Without the pyramid's model it is not reported; a library named twice is refused.
  r = run(facetscan() + " recognize " + scan.string() + " -l " + merged + " -q --json " + (d / "none.json"));
  ASSERT_EQ(r.code, 0) << r.out;
  const auto none = models_of(d.path / "none.json");
  EXPECT_EQ(std::count(none.begin(), none.end(), "truncated_pyramid"), 0);
  r = run(facetscan() + " recognize " + scan.string() + " -l " + a + " -l " + a + " -q");
  EXPECT_NE(r.code, 0);
  EXPECT_TRUE(contains(r.out, "facetscan: error: " + a + ": named twice among the library inputs")) << r.out;
}

}  // namespace
