// The sim-frame subcommand: renders a scene frame to PNG (and optional CSV ground truth).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <CLI/CLI.hpp>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "common/error.hpp"
#include "hw-sim/scene/sim_frame_cli.hpp"
#include "support/test_paths.hpp"

namespace {

namespace fsys = std::filesystem;

std::string slurp(const fsys::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void run_cli(std::vector<std::string> args) {
  CLI::App app("test");
  fs::sim::add_sim_frame_command(app);
  args.insert(args.begin(), "prog");
  std::vector<const char*> argv;
  for (auto& a : args) argv.push_back(a.c_str());
  app.parse(static_cast<int>(argv.size()), argv.data());
}

TEST(SimFrameCli, WritesPngAndTruth) {
  const auto dir = fsys::temp_directory_path() / ("fs_sim_frame_" + std::to_string(::getpid()));
  fsys::create_directories(dir);
  const std::string scene = (fs::test::source_dir() / "hw-sim/scenes/default.json").string();
  run_cli({"sim-frame", "--scene", scene, "--step", "250", "-o", (dir / "a.png").string(), "--seed", "3",
           "--truth", (dir / "a.csv").string()});
  run_cli({"sim-frame", "--scene", scene, "--step", "250", "-o", (dir / "b.png").string(), "--seed", "3"});
  run_cli({"sim-frame", "--scene", scene, "--step", "250", "-o", (dir / "c.png").string(), "--seed", "4"});
  run_cli({"sim-frame", "--scene", scene, "--step", "250", "-o", (dir / "d.png").string(), "--mono16",
           "--noise", "0"});
  const std::string a = slurp(dir / "a.png"), b = slurp(dir / "b.png"), c = slurp(dir / "c.png"),
                    d = slurp(dir / "d.png");
  ASSERT_GT(a.size(), 1000u);
  EXPECT_EQ(a.substr(1, 3), "PNG");
  EXPECT_EQ(a, b) << "same seed, same frame";
  EXPECT_NE(a, c) << "another seed, other noise";
  EXPECT_EQ(static_cast<unsigned char>(d[24]), 16u) << "Mono16 PNG bit depth";
  const std::string csv = slurp(dir / "a.csv");
  EXPECT_EQ(csv.rfind("row,column,x,y,z,object,face\n", 0), 0u);
  EXPECT_GT(std::count(csv.begin(), csv.end(), '\n'), 500);
  // Bad scene: an fs::Error naming the file.
  EXPECT_THROW(run_cli({"sim-frame", "--scene", (dir / "none.json").string(), "--step", "1", "-o",
                        (dir / "x.png").string()}),
               fs::Error);
  // Missing required option: CLI11's parse error.
  EXPECT_THROW(run_cli({"sim-frame", "--scene", scene}), CLI::ParseError);
  // The speckle grain: another frame than per-pixel speckle; out of range or not a number refused.
  run_cli({"sim-frame", "--scene", scene, "--step", "250", "-o", (dir / "e.png").string(), "--seed", "3",
           "--speckle-grain", "1.5"});
  EXPECT_NE(slurp(dir / "e.png"), a) << "a speckle grain changes the frame";
  for (const char* bad : {"9", "-1", "fine"})
    EXPECT_THROW(run_cli({"sim-frame", "--scene", scene, "--step", "250", "-o", (dir / "f.png").string(),
                          "--speckle-grain", bad}),
                 CLI::ParseError)
        << bad;
  fsys::remove_all(dir);
}

}  // namespace
