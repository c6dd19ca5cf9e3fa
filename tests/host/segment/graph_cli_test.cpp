// `facetscan graph` in-process (the command's CLI11 registration from host/cli/graph_commands.cpp).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "common/error.hpp"
#include "host/cli/commands.hpp"
#include "host/io/cloud_writers.hpp"
#include "host/pfrg/pfrg.hpp"
#include "support/test_paths.hpp"
#include "synthetic_scene.hpp"

namespace {

namespace stdfs = std::filesystem;

void run_cli(std::vector<std::string> args) {
  CLI::App app;
  fs::host::cli::add_graph_commands(app);
  std::vector<const char*> argv{"facetscan"};
  for (auto& a : args) argv.push_back(a.c_str());
  app.parse(int(argv.size()), const_cast<char**>(argv.data()));
}

stdfs::path temp_dir(const char* name) {
  const stdfs::path d =
      stdfs::temp_directory_path() / (std::string("fs_segment_") + name + "_" +
                                      std::to_string(::testing::UnitTest::GetInstance()->random_seed()));
  stdfs::remove_all(d);
  stdfs::create_directories(d);
  return d;
}

TEST(GraphCli, SyntheticPcdToPfrgJsonAndPictures) {
  fs::test::SyntheticScene sc;
  sc.objects.push_back(fs::test::make_pyramid({10, -5, 0}, 45, 55, 20));
  fs::test::SyntheticGrid g;
  fs::test::render(sc, g, 0.05);
  const stdfs::path dir = temp_dir("cli");
  fs::host::write_cloud((dir / "pyr.pcd").string(), g.cloud);
  run_cli({"graph", (dir / "pyr.pcd").string(), "-o", (dir / "graph.json").string(), "--pictures",
           (dir / "pics").string(), "--preset", "laser", "-q"});
  const fs::host::Pfrg pf = fs::host::read_pfrg_json(dir / "graph.json");
  ASSERT_EQ(pf.nodes.size(), 6u);  // SN + table + 4 faces
  int sn = 0;
  for (const auto& n : pf.nodes) {
    if (n.supernode) {
      ++sn;
      continue;
    }
    EXPECT_GT(n.area, 1000.0);
    EXPECT_NEAR(n.normal.norm(), 1.0, 1e-6);
    EXPECT_GT(n.normal.z(), 0.5);  // toward the camera above
  }
  EXPECT_EQ(sn, 1);
  EXPECT_EQ(pf.arcs.size(), 9u);  // 8 between faces + table to supernode
  for (const char* f : {"segmentation.png", "pfrg.svg", "enm.svg"}) {
    EXPECT_TRUE(stdfs::exists(dir / "pics" / f)) << f;
    EXPECT_GT(stdfs::file_size(dir / "pics" / f), 200u) << f;
  }
  std::ifstream svg(dir / "pics" / "pfrg.svg");
  const std::string text((std::istreambuf_iterator<char>(svg)), {});
  EXPECT_NE(text.find("mm²"), std::string::npos);
  stdfs::remove_all(dir);
}

TEST(GraphCli, MissingInputAndBadPresetAreErrors) {
  const stdfs::path dir = temp_dir("bad");
  EXPECT_THROW(run_cli({"graph", (dir / "nope.pcd").string(), "-o", (dir / "g.json").string()}), fs::Error);
  fs::host::OrganizedCloud c;
  c.reset(4, 4);
  fs::host::write_cloud((dir / "c.pcd").string(), c);
  EXPECT_THROW(
      run_cli({"graph", (dir / "c.pcd").string(), "-o", (dir / "g.json").string(), "--preset", "foo"}),
      fs::Error);
  stdfs::remove_all(dir);
}

}  // namespace
