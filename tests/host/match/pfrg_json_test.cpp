// PFRG JSON contract: round trip, validation errors naming the file and field.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "common/error.hpp"
#include "host/pfrg/pfrg.hpp"
#include "support/test_paths.hpp"

namespace {

using fs::host::Pfrg;
using nlohmann::json;

std::string error_of(const std::string& text) {
  try {
    fs::host::pfrg_from_json(json::parse(text), "g.json");
  } catch (const fs::Error& e) {
    return e.what();
  }
  return "";
}

TEST(PfrgJson, ContractExampleParses) {
  const Pfrg g = fs::host::pfrg_from_json(
      json::parse(R"({"nodes":[{"id":3,"area":1200.0,"normal":[0,0,1]},{"id":0,"supernode":true}],)"
                  R"("arcs":[{"a":3,"b":0,"border":40.0}]})"),
      "x");
  ASSERT_EQ(g.nodes.size(), 2u);
  EXPECT_EQ(g.nodes[0].id, 3);
  EXPECT_DOUBLE_EQ(g.nodes[0].area, 1200.0);
  EXPECT_TRUE(g.nodes[1].supernode);
  ASSERT_EQ(g.arcs.size(), 1u);
  EXPECT_DOUBLE_EQ(g.arcs[0].border, 40.0);
  EXPECT_EQ(g.find(0), &g.nodes[1]);
  EXPECT_EQ(g.find(5), nullptr);
}

TEST(PfrgJson, RoundTripThroughFile) {
  Pfrg g;
  g.name = "t";
  fs::host::PfrgNode a;
  a.id = 1;
  a.area = 12.5;
  a.normal = fs::Vec3(0, 0.6, 0.8);
  a.has_plane = true;
  a.offset = 3;
  a.centroid = fs::Vec3(1, 2, 3);
  g.nodes.push_back(a);
  fs::host::PfrgNode b;
  b.id = 7;
  b.supernode = true;
  g.nodes.push_back(b);
  g.arcs.push_back({1, 7, 4.25});
  g.observer = fs::Vec3(0, 0, 1);
  g.has_observer = true;
  const auto path = std::filesystem::temp_directory_path() / "fs_match_pfrg_roundtrip.json";
  fs::host::write_pfrg_json(g, path);
  const Pfrg r = fs::host::read_pfrg_json(path);
  std::filesystem::remove(path);
  EXPECT_EQ(r.name, "t");
  ASSERT_EQ(r.nodes.size(), 2u);
  EXPECT_TRUE(r.nodes[0].has_plane);
  EXPECT_NEAR((r.nodes[0].normal - a.normal).norm(), 0, 1e-15);
  EXPECT_NEAR((r.nodes[0].centroid - a.centroid).norm(), 0, 1e-15);
  EXPECT_TRUE(r.nodes[1].supernode);
  EXPECT_TRUE(r.has_observer);
  EXPECT_EQ(r.arcs[0].b, 7);
}

TEST(PfrgJson, NormalsAreNormalized) {
  const Pfrg g =
      fs::host::pfrg_from_json(json::parse(R"({"nodes":[{"id":1,"area":1,"normal":[0,0,5]}]})"), "x");
  EXPECT_DOUBLE_EQ(g.nodes[0].normal.z(), 1.0);
}

TEST(PfrgJson, ErrorsNameSourceAndField) {
  EXPECT_NE(error_of(R"([1,2])").find("g.json"), std::string::npos);
  EXPECT_NE(error_of(R"({"arcs":[]})").find("nodes: missing"), std::string::npos);
  EXPECT_NE(error_of(R"({"nodes":[{"id":1,"area":-1,"normal":[0,0,1]}]})").find("nodes[0].area: negative"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"nodes":[{"id":1,"area":1,"normal":[0,0]}]})").find("nodes[0].normal"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"nodes":[{"id":1,"area":1,"normal":[0,0,0]}]})").find("zero length"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"nodes":[{"id":1,"area":1,"normal":[0,0,1]},{"id":1,"supernode":true}]})")
                .find("nodes[1].id: duplicate"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"nodes":[{"id":1,"area":1,"normal":[0,0,1]}],"arcs":[{"a":1,"b":2}]})")
                .find("arcs[0].b: unknown node id 2"),
            std::string::npos);
  EXPECT_NE(
      error_of(R"({"nodes":[{"id":1,"area":1,"normal":[0,0,1]}],"arcs":[{"a":1,"b":1}]})").find("itself"),
      std::string::npos);
  EXPECT_NE(error_of(R"({"nodes":[{"id":1,"area":1,"normal":[0,0,1]},{"id":2,"area":1,"normal":[0,0,1]}],)"
                     R"("arcs":[{"a":1,"b":2},{"a":2,"b":1}]})")
                .find("duplicate arc"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"nodes":[{"id":"x","area":1,"normal":[0,0,1]}]})").find("nodes[0].id"),
            std::string::npos);
}

TEST(PfrgJson, SyntaxErrorNamesByteOffset) {
  const auto path = std::filesystem::temp_directory_path() / "fs_match_bad.json";
  std::ofstream(path) << "{\"nodes\": [ {\"id\": 1,, } ]}";
  try {
    fs::host::read_pfrg_json(path);
    FAIL() << "no error";
  } catch (const fs::Error& e) {
    EXPECT_NE(std::string(e.what()).find("at byte"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("fs_match_bad.json"), std::string::npos);
  }
  std::filesystem::remove(path);
  EXPECT_THROW(fs::host::read_pfrg_json("/nonexistent/x.json"), fs::Error);
}

}  // namespace
