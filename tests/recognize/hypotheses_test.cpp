// Unit tests of the hypothesis stage (host/recognize/hypotheses.hpp): the geometric prescore that ranks the
// hypotheses of all references before verification, and the support test.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <vector>

#include "common/mesh.hpp"
#include "host/library/library.hpp"
#include "host/library/model.hpp"
#include "host/recognize/hypotheses.hpp"
#include "host/recognize/report.hpp"
#include "support/test_paths.hpp"

namespace {

using fs::Mat3;
using fs::Vec3;
using fs::host::PfrgNode;
using fs::host::rec::FaceMatch;
using fs::host::rec::Hypothesis;

fs::host::Model cube_model() {
  return fs::host::build_model(fs::read_mesh(fs::test::source_dir() / "hw-sim/scenes/meshes/cube.off"));
}

// A scene graph holding the cube's faces that face up (+z, toward a sensor 500 mm above), in the cube's own
// pose (identity), with each face area multiplied by area_scale; node id = face index + 1.
struct CubeScene {
  fs::host::Library library;
  fs::host::Pfrg scene;
  std::vector<int> index;
  fs::host::rec::RecognizeParams params;
  Vec3 viewpoint;
};

CubeScene make_cube_scene(double area_scale) {
  CubeScene c;
  c.library.add(cube_model());
  const auto& m = c.library.models[0];
  c.viewpoint = m.center + Vec3(300, 250, 300);   // oblique: three faces well in view
  for (std::size_t f = 0; f < m.faces.size(); ++f) {
    const auto& mf = m.faces[f];
    if ((c.viewpoint - mf.centroid).dot(mf.normal) <= 0) continue;
    PfrgNode n;
    n.id = static_cast<int>(f) + 1;
    n.area = mf.area * area_scale;
    n.normal = mf.normal;
    n.offset = mf.offset;
    n.centroid = mf.centroid;
    n.has_plane = true;
    c.scene.nodes.push_back(n);
  }
  c.index.assign(m.faces.size() + 1, -1);
  for (std::size_t i = 0; i < c.scene.nodes.size(); ++i) c.index[static_cast<std::size_t>(c.scene.nodes[i].id)] = static_cast<int>(i);
  return c;
}

Hypothesis all_visible_matched(const CubeScene& c, std::size_t keep = 1000) {
  Hypothesis h;
  h.model = 0;
  for (std::size_t i = 0; i < c.scene.nodes.size() && i < keep; ++i)
    h.matches.push_back(FaceMatch{c.scene.nodes[i].id, c.scene.nodes[i].id - 1, false});
  return h;
}

TEST(Prescore, AllVisibleFacesMatchedExplainsTheView) {
  const CubeScene c = make_cube_scene(1.0);
  ASSERT_GE(c.scene.nodes.size(), 2u);
  const fs::host::rec::HypothesisContext hc{c.library, c.scene, c.index, c.viewpoint, c.params};
  EXPECT_NEAR(fs::host::rec::prescore(hc, all_visible_matched(c)), 1.0, 1e-9);
}

TEST(Prescore, MissingFacesLowerIt) {
  const CubeScene c = make_cube_scene(1.0);
  const fs::host::rec::HypothesisContext hc{c.library, c.scene, c.index, c.viewpoint, c.params};
  const double all = fs::host::rec::prescore(hc, all_visible_matched(c));
  const double one = fs::host::rec::prescore(hc, all_visible_matched(c, 1));
  EXPECT_LT(one, 0.8 * all);
  EXPECT_GT(one, 0.0);
}

TEST(Prescore, SceneFacesLargerThanTheModelsArePenalized) {
  // The same correspondences, but every scene face twice the model face: a smaller model than the object.
  const CubeScene c = make_cube_scene(2.0);
  const fs::host::rec::HypothesisContext hc{c.library, c.scene, c.index, c.viewpoint, c.params};
  EXPECT_LT(fs::host::rec::prescore(hc, all_visible_matched(c)), 0.7);
  // Within the segmentation slack (1.1x) there is no penalty.
  const CubeScene ok = make_cube_scene(1.08);
  const fs::host::rec::HypothesisContext hk{ok.library, ok.scene, ok.index, ok.viewpoint, ok.params};
  EXPECT_NEAR(fs::host::rec::prescore(hk, all_visible_matched(ok)), 1.0, 1e-9);
}

TEST(Support, RestingOnTheTableIsSupported) {
  const auto m = cube_model();
  const fs::Plane table{Vec3::UnitZ(), 0.0};
  const Mat3 R = Mat3::Identity();
  double low = -1;
  // cube.off rests on z = 0.
  EXPECT_EQ(fs::host::rec::support_factor(m, R, Vec3::Zero(), table, {}, {}, &low), 1.0);
  EXPECT_NEAR(low, 0.0, 1e-9);
}

TEST(Support, FloatingWithNothingBelowIsNot) {
  const auto m = cube_model();
  const fs::Plane table{Vec3::UnitZ(), 0.0};
  const Mat3 R = Mat3::Identity();
  double low = 0;
  const fs::host::rec::SupportParams p{.tol_mm = 3.0, .radius_mm = 6.0, .unsupported = 0.5};
  // Table points far away (the floor around it) do not hold it up.
  std::vector<Eigen::Vector3f> pts{Eigen::Vector3f(200, 200, 0), Eigen::Vector3f(-150, 0, 0)};
  EXPECT_EQ(fs::host::rec::support_factor(m, R, Vec3(0, 0, 20), table, pts, p, &low), 0.5);
  EXPECT_NEAR(low, 20.0, 1e-9);
  // Sunk into the table.
  EXPECT_EQ(fs::host::rec::support_factor(m, R, Vec3(0, 0, -10), table, pts, p), 0.5);
}

TEST(Support, StackedOnMeasuredSurfaceIsSupported) {
  const auto m = cube_model();
  const fs::Plane table{Vec3::UnitZ(), 0.0};
  double low = 0;
  // Lift the cube 20 mm and put a measured point of "something below" 2 mm under its lowest vertex.
  fs::host::rec::support_factor(m, Mat3::Identity(), Vec3(0, 0, 20), table, {}, {}, &low);
  Vec3 v_low = Vec3::Zero();
  double best = 1e300;
  for (const auto& f : m.faces)
    for (const auto& loop : f.loops)
      for (const Vec3& v : loop)
        if (v.z() + 20 < best) best = v.z() + 20, v_low = v + Vec3(0, 0, 20);
  std::vector<Eigen::Vector3f> pts{(v_low - Vec3(0, 0, 2)).cast<float>()};
  EXPECT_EQ(fs::host::rec::support_factor(m, Mat3::Identity(), Vec3(0, 0, 20), table, pts, {}), 1.0);
}

}  // namespace

namespace {

TEST(Report, AxisAngleTextHidesTheAxisOfRotationsBelowDisplayPrecision) {
  using fs::host::rec::axis_angle_text;
  const std::string zero = axis_angle_text(Mat3::Identity());
  EXPECT_NE(zero.find("0.0° about ( 0.00,  0.00,  1.00)"), std::string::npos) << zero;
  const Mat3 tiny(Eigen::AngleAxisd(0.01 * M_PI / 180.0, Vec3(0.36, 0.76, -0.54).normalized()));
  EXPECT_EQ(axis_angle_text(tiny), zero);
  const Mat3 quarter(Eigen::AngleAxisd(M_PI / 2, Vec3::UnitX()));
  EXPECT_NE(axis_angle_text(quarter).find("90.0° about ( 1.00,  0.00,  0.00)"), std::string::npos)
      << axis_angle_text(quarter);
}

}  // namespace
