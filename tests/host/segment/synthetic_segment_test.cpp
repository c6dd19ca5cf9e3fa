// Segmentation + scene PFRG on synthetic organized grids (convex polyhedra on a table seen from above).
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>

#include <Eigen/Eigenvalues>

#include "common/error.hpp"
#include "host/segment/quality.hpp"
#include "host/segment/scene_pfrg.hpp"
#include "host/segment/segmenter.hpp"
#include "synthetic_scene.hpp"

namespace {

using namespace fs::host;
using namespace fs::host::seg;

struct Result {
  Segmentation seg;
  Pfrg graph;
  PreprocessStats stats;
  HooverResult hoover;
};

// The true normal of a ground-truth face: plane fit of the noise-free points.
std::map<std::int32_t, fs::Vec3> true_normals(const fs::test::SyntheticGrid& g) {
  std::map<std::int32_t, std::vector<fs::Vec3>> pts;
  for (std::size_t i = 0; i < g.face.size(); ++i)
    if (g.face[i] >= 0) pts[g.face[i]].push_back(g.true_points[i]);
  std::map<std::int32_t, fs::Vec3> out;
  for (auto& [f, v] : pts) {
    fs::Vec3 m = fs::Vec3::Zero();
    for (auto& p : v) m += p;
    m /= double(v.size());
    fs::Mat3 C = fs::Mat3::Zero();
    for (auto& p : v) C += (p - m) * (p - m).transpose();
    Eigen::SelfAdjointEigenSolver<fs::Mat3> es(C);
    out[f] = es.eigenvectors().col(0);
  }
  return out;
}

Result run(const fs::test::SyntheticScene& sc, double noise) {
  fs::test::SyntheticGrid g;
  fs::test::render(sc, g, noise);
  Result r;
  Segmenter s;
  s.segment(g.cloud, r.seg);
  ScenePfrgBuilder b;
  b.build(r.seg, r.graph, &r.stats);
  const auto tn = true_normals(g);
  r.hoover = hoover_compare(g.face, r.seg, 0.8, [&](std::int32_t f) -> std::optional<fs::Vec3> {
    auto it = tn.find(f);
    if (it == tn.end()) return std::nullopt;
    return it->second;
  });
  return r;
}

std::set<std::pair<int, int>> arcs_between_known(const Pfrg& g) {
  std::set<std::pair<int, int>> out;
  for (const auto& a : g.arcs)
    if (a.a != 0 && a.b != 0) out.insert({std::min(a.a, a.b), std::max(a.a, a.b)});
  return out;
}

TEST(SyntheticSegment, PyramidFacesDetectedWithAccurateNormals) {
  fs::test::SyntheticScene sc;
  sc.objects.push_back(fs::test::make_pyramid({10, -5, 0}, 45, 55, 20));
  const Result r = run(sc, 0.05);
  EXPECT_EQ(r.hoover.gt_regions, 5);  // table + 4 slanted faces
  EXPECT_EQ(r.hoover.correct, 5) << "over " << r.hoover.over << " under " << r.hoover.under << " missed "
                                 << r.hoover.missed << " noise " << r.hoover.noise;
  EXPECT_LT(r.hoover.max_angle_error_deg, 1.0);
  // PFRG: supernode + table + 4 faces; every slanted face touches its two neighbours and the table.
  ASSERT_EQ(r.graph.nodes.size(), 6u);
  const auto arcs = arcs_between_known(r.graph);
  EXPECT_EQ(arcs.size(), 8u);
}

}  // namespace

// A cloud without a grid (a PLY with no grid information) is refused with a message that says why; the same
// points with their grid segment.
TEST(SyntheticSegment, UnorganizedCloudIsRefused) {
  fs::test::SyntheticScene sc;
  sc.objects.push_back(fs::test::make_box({0, 0, 20}, {20, 20, 20}, 10));
  fs::test::SyntheticGrid g;
  fs::test::render(sc, g);
  Segmenter s;
  Segmentation seg;
  EXPECT_NO_THROW(s.segment(g.cloud, seg));
  fs::host::OrganizedCloud flat = g.cloud;
  flat.organized = false;
  flat.width = static_cast<std::uint32_t>(flat.points.size());
  flat.height = 1;
  try {
    s.segment(flat, seg);
    ADD_FAILURE() << "an unorganized cloud was segmented";
  } catch (const fs::Error& e) {
    EXPECT_NE(std::string(e.what()).find("the cloud has no grid"), std::string::npos) << e.what();
  }
}
