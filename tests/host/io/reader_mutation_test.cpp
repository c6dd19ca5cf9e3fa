// The fuzz seeds parse, and random mutations of them (byte flips, truncations, inserted digits) only ever
// produce a cloud or fs::Error: a cheap in-process stand-in for the libFuzzer runs (fuzz_pcd_reader,
// fuzz_ply_reader), run under ASan/UBSan in CI.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>

#include "common/error.hpp"
#include "host/io/cloud_readers.hpp"
#include "support/test_paths.hpp"

namespace fs::host {
namespace {

std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

template <typename Reader>
void mutate_and_read(const std::filesystem::path& dir, Reader read, std::size_t& parsed_seeds) {
  std::mt19937 rng(1234);
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    const std::string seed = slurp(e.path());
    OrganizedCloud cloud;
    CloudReadOptions opt;
    opt.max_points = 1u << 20;
    auto attempt = [&](const std::string& bytes) -> bool {
      try {
        read(std::span(reinterpret_cast<const std::byte*>(bytes.data()), bytes.size()), cloud, opt);
        EXPECT_EQ(cloud.points.size(), std::size_t(cloud.width) * cloud.height);
        return true;
      } catch (const fs::Error&) {
        return false;
      }
    };
    const std::string fname = e.path().filename().string();
    if (fname.find("truncated") == std::string::npos && fname.find("regress") == std::string::npos) {
      EXPECT_TRUE(attempt(seed)) << e.path();
      ++parsed_seeds;
    }
    for (int i = 0; i < 400; ++i) {
      std::string m = seed;
      const int kind = i % 4;
      std::uniform_int_distribution<std::size_t> pos(0, m.size() - 1);
      if (kind == 0) {
        m[pos(rng)] = static_cast<char>(rng());
      } else if (kind == 1) {
        m.resize(pos(rng));
      } else if (kind == 2) {
        m.insert(pos(rng), std::to_string(rng() % 100000));
      } else {
        for (int k = 0; k < 4; ++k) m[pos(rng)] = "0123456789 \n-.e"[rng() % 15];
      }
      attempt(m);
    }
  }
}

TEST(ReaderMutation, PcdSeedsParseAndMutationsFailCleanly) {
  std::size_t parsed = 0;
  mutate_and_read(
      fs::test::source_dir() / "tests/host/io/corpus/pcd_reader",
      [](std::span<const std::byte> b, OrganizedCloud& c, const CloudReadOptions& o) {
        read_pcd(b, "m.pcd", c, o);
      },
      parsed);
  EXPECT_GE(parsed, 4u);
}

TEST(ReaderMutation, PlySeedsParseAndMutationsFailCleanly) {
  std::size_t parsed = 0;
  mutate_and_read(
      fs::test::source_dir() / "tests/host/io/corpus/ply_reader",
      [](std::span<const std::byte> b, OrganizedCloud& c, const CloudReadOptions& o) {
        read_ply(b, "m.ply", c, o);
      },
      parsed);
  EXPECT_GE(parsed, 3u);
}

}  // namespace
}  // namespace fs::host
