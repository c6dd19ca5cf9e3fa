// Unit tests of the hypothesis stage (host/recognize/hypotheses.hpp): the geometric prescore that ranks the
// hypotheses of all references before verification, and the support test.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <random>
#include <span>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/mesh.hpp"
#include "host/library/library.hpp"
#include "host/library/model.hpp"
#include "host/library/polycubes.hpp"
#include "host/recognize/hypotheses.hpp"
#include "host/recognize/pose.hpp"
#include "host/recognize/recognizer.hpp"
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
  c.viewpoint = m.center + Vec3(300, 250, 300);  // oblique: three faces well in view
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
  for (std::size_t i = 0; i < c.scene.nodes.size(); ++i)
    c.index[static_cast<std::size_t>(c.scene.nodes[i].id)] = static_cast<int>(i);
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

// A stair of three cubes (edge 20 mm): two along x, the third on top of the second. Its two top faces
// (+z at z = 20 and z = 40) and its two -x faces (x = 0 and x = 20) are parallel pairs a cube apart.
struct Stair {
  fs::host::Model model = fs::host::polycube_model({{0, 0, 0}, {1, 0, 0}, {1, 0, 1}}, 20.0, "stair");
  int face(const Vec3& n, double offset) const {
    for (std::size_t f = 0; f < model.faces.size(); ++f)
      if (model.faces[f].normal.dot(n) > 0.999 && std::abs(model.faces[f].offset - offset) < 1e-6)
        return static_cast<int>(f);
    ADD_FAILURE() << "no face";
    return 0;
  }
  // The scene face of model face f seen whole in pose (R, t), matched to model face `as`.
  fs::host::rec::PlanePair seen(int f, int as, const Mat3& R, const Vec3& t) const {
    const auto& mf = model.faces[static_cast<std::size_t>(f)];
    const Vec3 n = R * mf.normal;
    const Vec3 c = R * mf.centroid + t;
    return {n, n.dot(c), c, mf.area, as};
  }
};

TEST(Placement, OutsideFaceIsTheDistanceToTheOutlineOfTheFace) {
  const Stair s;
  const auto& top = s.model.faces[static_cast<std::size_t>(s.face(Vec3::UnitZ(), 20.0))];  // x, y in 0..20
  EXPECT_DOUBLE_EQ(fs::host::rec::outside_face_mm(top, Vec3(10, 10, 20)), 0.0);
  EXPECT_DOUBLE_EQ(fs::host::rec::outside_face_mm(top, Vec3(1, 19, 25)), 0.0);  // off the plane: projected
  EXPECT_NEAR(fs::host::rec::outside_face_mm(top, Vec3(30, 10, 20)), 10.0, 1e-9);
  EXPECT_NEAR(fs::host::rec::outside_face_mm(top, Vec3(23, 24, 20)), 5.0, 1e-9);
  // The -y side is L-shaped (three squares): the missing square's middle is 10 mm outside it.
  const auto& side = s.model.faces[static_cast<std::size_t>(s.face(-Vec3::UnitY(), 0.0))];
  EXPECT_DOUBLE_EQ(fs::host::rec::outside_face_mm(side, Vec3(30, 0, 30)), 0.0);
  EXPECT_NEAR(fs::host::rec::outside_face_mm(side, Vec3(15, 0, 25)), 5.0, 1e-9);
  EXPECT_NEAR(fs::host::rec::outside_face_mm(side, Vec3(10, 0, 35)), 10.0, 1e-9);
}

TEST(Placement, OnlyTheTrueCorrespondenceOfParallelFacesIsOnePlacement) {
  const Stair s;
  const Mat3 R = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  const Vec3 t(100, -50, 400);
  const int top_low = s.face(Vec3::UnitZ(), 20.0), top_high = s.face(Vec3::UnitZ(), 40.0);
  const int px = s.face(Vec3::UnitX(), 40.0), my = s.face(-Vec3::UnitY(), 0.0);
  const fs::host::rec::PlacementCheck check;
  using Pairs = std::vector<fs::host::rec::PlanePair>;
  // The true correspondence of four faces (two of them parallel).
  const Pairs truth{s.seen(top_low, top_low, R, t), s.seen(top_high, top_high, R, t), s.seen(px, px, R, t),
                    s.seen(my, my, R, t)};
  EXPECT_TRUE(fs::host::rec::consistent_placement(s.model, R, truth, check));
  EXPECT_NEAR(fs::host::rec::fit_translation(s.model, R, truth).t.x(), t.x(), 1e-9);
  // The two tops swapped: same normals, same areas, no translation puts both where they are seen.
  const Pairs swapped{s.seen(top_low, top_high, R, t), s.seen(top_high, top_low, R, t), s.seen(px, px, R, t),
                      s.seen(my, my, R, t)};
  EXPECT_GT(fs::host::rec::fit_translation(s.model, R, swapped).rms_mm, check.rms_mm);
  EXPECT_FALSE(fs::host::rec::consistent_placement(s.model, R, swapped, check));
  // Three faces that fix the translation, the upper top taken for the lower: the planes agree (one cube
  // up), but the top is then seen a cube beside the top it is matched to.
  const Pairs shifted{s.seen(top_high, top_low, R, t), s.seen(px, px, R, t), s.seen(my, my, R, t)};
  EXPECT_LT(fs::host::rec::fit_translation(s.model, R, shifted).rms_mm, 1e-9);
  EXPECT_FALSE(fs::host::rec::consistent_placement(s.model, R, shifted, check));
  const Pairs right{s.seen(top_high, top_high, R, t), s.seen(px, px, R, t), s.seen(my, my, R, t)};
  EXPECT_TRUE(fs::host::rec::consistent_placement(s.model, R, right, check));
  // A face seen in part (its visible part's centroid) still lies on its model face.
  Pairs partial = right;
  partial[2].scene_centroid = R * Vec3(32, 0, 30) + t;  // the -y face's upper square
  EXPECT_TRUE(fs::host::rec::consistent_placement(s.model, R, partial, check));
  // Two faces leave the translation open along their common edge: no test of where they lie.
  const Pairs two{s.seen(top_high, top_low, R, t), s.seen(my, my, R, t)};
  EXPECT_TRUE(fs::host::rec::consistent_placement(s.model, R, two, check));
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

// A solid's own seen face going on below it holds nothing up (SupportParams::own_plane_mm): the top part of a
// larger solid, fitted by a smaller model, has that larger solid's faces measured under its lowest point. A
// surface off those planes, 2 mm in front of the face, still holds it up.
TEST(Support, ItsOwnSeenFaceGoingOnBelowItHoldsNothingUp) {
  const auto m = cube_model();
  const fs::Plane table{Vec3::UnitZ(), 0.0};
  const Mat3 R = Mat3::Identity();
  const Vec3 t(0, 0, 20);
  Vec3 v_low = Vec3::Zero();
  ASSERT_NEAR(fs::host::rec::lowest_point(m, R, t, table, &v_low), 20.0, 1e-9);
  // A side face through the lowest vertex, and a sensor in front of it and above.
  Vec3 n = Vec3::Zero();
  for (const auto& f : m.faces)
    if (std::abs(f.normal.z()) < 0.1 && std::abs(f.normal.dot(v_low - t) - f.offset) < 1e-6) n = f.normal;
  ASSERT_GT(n.norm(), 0.5);
  const Vec3 e = n.cross(Vec3::UnitZ());
  fs::host::rec::SupportParams p{.viewpoint = v_low + 300.0 * n + Vec3(0, 0, 300)};
  std::vector<Eigen::Vector3f> face_below;  // the face's plane, 2-5 mm under the vertex
  for (double down = 2.0; down <= 5.0; down += 1.0)
    for (double along = -3.0; along <= 3.0; along += 1.0)
      face_below.push_back((v_low - down * Vec3::UnitZ() + along * e).cast<float>());
  p.own_plane_mm = 0.0;
  EXPECT_EQ(fs::host::rec::support_factor(m, R, t, table, face_below, p), 1.0);
  p.own_plane_mm = 0.5;
  EXPECT_EQ(fs::host::rec::support_factor(m, R, t, table, face_below, p), 0.5);
  const std::vector<Eigen::Vector3f> in_front{(v_low - 2.0 * Vec3::UnitZ() + 2.0 * n).cast<float>()};
  EXPECT_EQ(fs::host::rec::support_factor(m, R, t, table, in_front, p), 1.0);
  // A face turned away from the sensor does not count as seen: its plane's points hold the solid up.
  p.viewpoint = v_low - 300.0 * n + Vec3(0, 0, 300);
  EXPECT_EQ(fs::host::rec::support_factor(m, R, t, table, face_below, p), 1.0);
}

// The space under a floating solid (look_below), the sensor looking in at a slant: with only the table
// measured, rays pass through the space under the lowest point and end on the table beyond it (seen through);
// with a surface measured in front of that space (something the solid rests on is hidden behind it), the rays
// end before it (hidden). Only the hidden case holds the solid up.
TEST(Support, SpaceHiddenUnderAFloatingSolidHoldsItUpSpaceSeenThroughDoesNot) {
  const fs::Plane table{Vec3::UnitZ(), 0.0};
  const Vec3 viewpoint(0, -300, 400);
  auto grid = [](double z) {
    std::vector<Eigen::Vector3f> pts;
    for (int x = -100; x <= 100; ++x)
      for (int y = -100; y <= 100; ++y) pts.emplace_back(float(x), float(y), float(z));
    return pts;
  };
  const std::vector<Eigen::Vector3f> table_pts = grid(0.0), plate = grid(90.0);
  const Vec3 lowest(0, 0, 20);
  const auto open = fs::host::rec::look_below(lowest, table, viewpoint, table_pts, 3.0);
  EXPECT_GT(open.seen_through, 0);
  EXPECT_EQ(open.hidden, 0);
  const auto hidden = fs::host::rec::look_below(lowest, table, viewpoint, plate, 3.0);
  EXPECT_EQ(hidden.seen_through, 0);
  EXPECT_GE(hidden.hidden, 3);
  // Resting on the table: no space to probe.
  const Vec3 resting(0, 0, 2);
  const auto none = fs::host::rec::look_below(resting, table, viewpoint, plate, 3.0);
  EXPECT_EQ(none.hidden + none.seen_through, 0);

  // The support test with look_below: the cube lifted 20 mm.
  const auto m = cube_model();
  fs::host::rec::SupportParams p{.tol_mm = 3.0, .radius_mm = 6.0, .unsupported = 0.5};
  p.viewpoint = viewpoint;
  const Vec3 up(0, 0, 20);
  EXPECT_EQ(fs::host::rec::support_factor(m, Mat3::Identity(), up, table, plate, p), 0.5);  // off
  p.look_below = true;
  EXPECT_EQ(fs::host::rec::support_factor(m, Mat3::Identity(), up, table, plate, p), 1.0);
  EXPECT_EQ(fs::host::rec::support_factor(m, Mat3::Identity(), up, table, table_pts, p), 0.5);
  // No ray of a measured point passes that space (what holds the solid up is in the laser's shadow): nothing
  // is seen through it, and it holds the solid up unless rays that end in front of it are asked for.
  const std::vector<Eigen::Vector3f> nothing_near{Eigen::Vector3f(140.0f, 140.0f, 0.0f)};
  const auto unseen = fs::host::rec::look_below(lowest, table, viewpoint, nothing_near, 3.0);
  EXPECT_EQ(unseen.hidden + unseen.seen_through, 0);
  EXPECT_EQ(fs::host::rec::support_factor(m, Mat3::Identity(), up, table, nothing_near, p), 1.0);
  p.min_hidden_rays = 3;
  EXPECT_EQ(fs::host::rec::support_factor(m, Mat3::Identity(), up, table, nothing_near, p), 0.5);
  EXPECT_EQ(fs::host::rec::support_factor(m, Mat3::Identity(), up, table, plate, p), 1.0);
}

// The measured points of a scene of posed cubes over the table (z = 0, x and y within 150 mm), seen from
// `viewpoint`: each ray toward a table grid point ends on the nearest cube it meets first.
struct PosedCube {
  Mat3 R;
  Vec3 t;
};
// `step_mm`: the table grid's spacing.
std::vector<Eigen::Vector3f> render_cubes(const fs::host::rec::ModelGeometry& g,
                                          std::span<const PosedCube> cubes, const Vec3& viewpoint,
                                          int step_mm = 1) {
  std::vector<Eigen::Vector3f> pts;
  for (int x = -150; x <= 150; x += step_mm)
    for (int y = -150; y <= 150; y += step_mm) {
      const Vec3 q(x, y, 0.0);
      double end = (q - viewpoint).norm();
      const Vec3 u = (q - viewpoint) / end;
      for (const PosedCube& c : cubes) {
        double hit = 0.0;
        if (g.cast(c.R.transpose() * (viewpoint - c.t), c.R.transpose() * u, hit) >= 0 && hit < end)
          end = hit;
      }
      pts.push_back(Vec3(viewpoint + end * u).cast<float>());
    }
  return pts;
}

// What holds a solid up is under its centre of mass: the column below it. A cube over a table in full view,
// high enough for the sensor to see the table under its centre, is not held up, whatever its turn about the
// vertical. One resting on a pedestal under its centre is, though the table is seen under its overhanging
// near edge (probing under its base vertices instead would call it floating). Lower, the cube hides the space
// under its centre itself: that may hold a pedestal, and a solid seen clearly is held up. (Within radius_mm
// of the table, a table point right under its lowest point holds it up: not looked at here.)
TEST(Support, TheColumnUnderTheCentreOfMassHoldsASolidUp) {
  const fs::Plane table{Vec3::UnitZ(), 0.0};
  const Vec3 viewpoint(0, -300, 400);
  const auto m = cube_model();
  const fs::host::rec::ModelGeometry g(m);
  fs::host::rec::SupportParams p{.tol_mm = 3.0, .radius_mm = 6.0, .unsupported = 0.5};
  p.viewpoint = viewpoint;
  p.look_below = true;
  for (const double yaw_deg : {0.0, 30.0, 45.0, 90.0, 180.0}) {
    const Mat3 R(Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Vec3::UnitZ()));
    const PosedCube high{R, Vec3(0, 0, 60)};
    EXPECT_EQ(
        fs::host::rec::support_factor(m, high.R, high.t, table, render_cubes(g, {&high, 1}, viewpoint), p),
        0.5)
        << yaw_deg << " deg";
    // The pedestal: a cube whose top (z = 20) is under the upper cube's centre and far half.
    const std::array<PosedCube, 2> stack{PosedCube{R, Vec3(0, 0, 20)},
                                         PosedCube{Mat3::Identity(), Vec3(0, 10, -30)}};
    const auto pts = render_cubes(g, stack, viewpoint);
    EXPECT_EQ(fs::host::rec::support_factor(m, R, stack[0].t, table, pts, p), 1.0) << yaw_deg << " deg";
    // Under the overhanging near edge the pedestal's front is seen beyond the space below the base.
    const Vec3 edge = R * Vec3(0, -25, 0) + stack[0].t;
    if (yaw_deg == 0.0) {
      EXPECT_GT(fs::host::rec::look_below(edge, table, viewpoint, pts, 3.0).seen_through, 0);
    }
    const PosedCube low{R, Vec3(0, 0, 10)};
    EXPECT_EQ(fs::host::rec::support_factor(m, low.R, low.t, table, render_cubes(g, {&low, 1}, viewpoint), p),
              1.0)
        << yaw_deg << " deg";
  }
}

// The column is probed by the rays passing within 3 mm of it, twice the fine samples' spacing: seen nearly
// from above, where the column is end-on, and sampled on a 2-3 mm grid, a cube 15-20 mm up whose centre
// column it hides itself still has enough rays ending in front of that column (within 1.5 mm it had two or
// fewer and was called floating).
TEST(Support, SparseSamplesStillProbeTheColumn) {
  const fs::Plane table{Vec3::UnitZ(), 0.0};
  const Vec3 viewpoint(0, -50, 400);  // nearly overhead: the column is seen end-on
  const auto m = cube_model();
  const fs::host::rec::ModelGeometry g(m);
  fs::host::rec::SupportParams p{.tol_mm = 3.0, .radius_mm = 6.0, .unsupported = 0.5};
  p.viewpoint = viewpoint;
  p.look_below = true;
  for (const int step_mm : {2, 3}) {
    for (const double lift : {15.0, 17.0, 20.0}) {
      const PosedCube cube{Mat3::Identity(), Vec3(0, 0, lift)};
      const auto pts = render_cubes(g, {&cube, 1}, viewpoint, step_mm);
      const auto below = fs::host::rec::look_below(Vec3(0, 0, lift), table, viewpoint, pts, 3.0);
      EXPECT_EQ(below.seen_through, 0) << step_mm << " mm grid, " << lift << " mm up";
      EXPECT_GE(below.hidden, 3) << step_mm << " mm grid, " << lift << " mm up";
      EXPECT_EQ(fs::host::rec::support_factor(m, cube.R, cube.t, table, pts, p), 1.0)
          << step_mm << " mm grid, " << lift << " mm up";
    }
  }
}

// The support test on a SampleSet visits only the blocks whose ray cones reach the place it asks about: the
// same answers as over every point, for cubes at random places, heights and turns over a scene of a stack, a
// lone cube and the table (both answers, and both ways of being held up, among them).
TEST(Support, SampleBlocksGiveTheAnswersOfEveryPoint) {
  const fs::Plane table{Vec3::UnitZ(), 0.0};
  const Vec3 viewpoint(0, -300, 400);
  const auto m = cube_model();
  const fs::host::rec::ModelGeometry g(m);
  const std::array<PosedCube, 3> scene{
      PosedCube{Mat3::Identity(), Vec3(0, 10, -30)}, PosedCube{Mat3::Identity(), Vec3(0, 0, 20)},
      PosedCube{Mat3(Eigen::AngleAxisd(0.4, Vec3::UnitZ())), Vec3(-70, 40, 0)}};
  const auto pts = render_cubes(g, scene, viewpoint);
  fs::host::OrganizedCloud cloud;
  cloud.reset(301, 301);  // render_cubes' grid: x by rows, y by columns
  std::copy(pts.begin(), pts.end(), cloud.points.begin());
  cloud.viewpoint = viewpoint;
  fs::host::rec::SampleSet samples;
  samples.build(cloud, fs::host::rec::SampleSteps{2, 2});
  const fs::host::rec::MeasuredPoints blocks(samples);
  const std::span<const Eigen::Vector3f> every(samples.points());
  fs::host::rec::SupportParams p{.tol_mm = 3.0, .radius_mm = 6.0, .unsupported = 0.5};
  p.viewpoint = viewpoint;
  p.look_below = true;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> x(-110, 110), y(-110, 110), z(4, 90), yaw(0, M_PI);
  int held = 0, not_held = 0, hidden_below = 0;
  for (int k = 0; k < 400; ++k) {
    const Mat3 R(Eigen::AngleAxisd(yaw(rng), Vec3::UnitZ()));
    const Vec3 t(x(rng), y(rng), z(rng));
    const double a = fs::host::rec::support_factor(m, R, t, table, blocks, p);
    ASSERT_EQ(a, fs::host::rec::support_factor(m, R, t, table, every, p)) << k;
    (a == 1.0 ? held : not_held) += 1;
    const auto b = fs::host::rec::look_below(t, table, viewpoint, blocks, 3.0);
    const auto e = fs::host::rec::look_below(t, table, viewpoint, every, 3.0);
    ASSERT_EQ(b.hidden, e.hidden) << k;
    ASSERT_EQ(b.seen_through, e.seen_through) << k;
    hidden_below += e.hidden > 0 ? 1 : 0;
  }
  EXPECT_GT(held, 20);
  EXPECT_GT(not_held, 100);
  EXPECT_GT(hidden_below, 20);
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

namespace {

// Scene node `id` for model face `f` in pose (R, t): its plane, centroid and area.
PfrgNode posed_face_node(const fs::host::Model& m, std::size_t f, const Mat3& R, const Vec3& t, int id) {
  PfrgNode face;
  face.id = id;
  face.normal = R * m.faces[f].normal;
  face.centroid = R * m.faces[f].centroid + t;
  face.offset = face.normal.dot(face.centroid);
  face.area = m.faces[f].area;
  face.has_plane = true;
  return face;
}

// A pentagonal pyramid (library model 0, a cube after it) lying on the table z = 0 on one of its triangles g:
// R maps g's normal to -z, then turns it by yaw_deg about the vertical; placed at (x, y). `face` is its
// tilted base seen whole (scene node `face_id`).
struct PyramidOnItsSide {
  PyramidOnItsSide(double yaw_deg, double x, double y, int face_id) {
    lib.add(fs::host::build_model(
        fs::read_mesh(fs::test::shared_data() / "polyhedra/polyhedra-viewer/off/pentagonal-pyramid.off"),
        {.scale = 40.0}));
    lib.add(cube_model());
    const fs::host::Model& m = lib.models[0];
    std::size_t g = 0;
    for (std::size_t f = 0; f < m.faces.size(); ++f) {
      if (m.faces[f].loops[0].size() == 3 && g == 0) g = f;
      if (m.faces[f].loops[0].size() == 5) base = f;
    }
    const Mat3 Rtilt =
        Eigen::Quaterniond::FromTwoVectors(m.faces[g].normal, Vec3(0, 0, -1)).toRotationMatrix();
    R = Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Vec3::UnitZ()).toRotationMatrix() * Rtilt;
    t = Vec3(x, y, -(R * m.faces[g].centroid).z());  // face g on z = 0
    face = posed_face_node(m, base, R, t, face_id);
  }
  fs::host::Library lib;
  std::size_t base = 0;  // the pentagon
  Mat3 R;
  Vec3 t;
  PfrgNode face;
};

// Single-face hypotheses: a pentagonal pyramid lying on one of its triangles shows only its tilted base. The
// true pose must be among the hypotheses exactly (rotation up to the model's symmetry, model centre within
// 1e-6 mm), every hypothesis must put some face of its model on the table and its matched face on the scene
// face's plane, and a horizontal face (pose about the vertical open) or a face larger than every model face
// gives none.
TEST(SingleFaceHypotheses, RecoverTheRestingPoseFromOneFaceAndTheTable) {
  const PyramidOnItsSide scene(30.0, -50, 20, 5);
  const fs::host::Library& lib = scene.lib;
  const fs::host::Model& m = lib.models[0];
  const Mat3& R = scene.R;
  const Vec3& t = scene.t;
  const PfrgNode& face = scene.face;
  fs::Plane table;                  // z = 0, normal up
  ASSERT_GT(face.normal.z(), 0.2);  // tilted toward the sensor, not horizontal

  std::vector<Hypothesis> out(64);
  for (auto& h : out) h.matches.reserve(4);
  const int n = fs::host::rec::single_face_hypotheses(lib, face, table, {}, out);
  ASSERT_GT(n, 0);
  bool found = false;
  for (int k = 0; k < n; ++k) {
    const Hypothesis& h = out[static_cast<std::size_t>(k)];
    const fs::host::Model& hm = lib.models[static_cast<std::size_t>(h.model)];
    ASSERT_EQ(h.matches.size(), 1u);
    EXPECT_EQ(h.matches[0].scene, 5);
    const auto& mf = hm.faces[static_cast<std::size_t>(h.matches[0].ref)];
    EXPECT_NEAR((h.R * mf.normal).dot(face.normal), 1.0, 1e-9);
    EXPECT_NEAR(face.normal.dot(h.R * mf.centroid + h.t), face.offset, 1e-9);
    double lowest = 1e9;
    for (const auto& f : hm.faces)
      for (const Vec3& v : f.loops[0]) lowest = std::min(lowest, (h.R * v + h.t).z());
    EXPECT_LT(std::abs(lowest), 0.7) << hm.name;  // some face rests on the table (within the angle tolerance)
    if (h.model == 0 && fs::host::rec::rotation_angle_deg_sym(R, h.R, m) < 1e-6 &&
        ((R * m.center + t) - (h.R * m.center + h.t)).norm() < 1e-6)
      found = true;
  }
  EXPECT_TRUE(found);

  PfrgNode flat = face;
  flat.normal = Vec3::UnitZ();
  EXPECT_EQ(fs::host::rec::single_face_hypotheses(lib, flat, table, {}, out), 0);
  PfrgNode huge = face;
  huge.area = 1e7;
  EXPECT_EQ(fs::host::rec::single_face_hypotheses(lib, huge, table, {}, out), 0);
  // The output span bounds what is written.
  EXPECT_EQ(fs::host::rec::single_face_hypotheses(lib, face, table, {}, std::span<Hypothesis>(out.data(), 1)),
            1);
}

// The same pyramid with its base partly hidden: only the part of the pentagon on one side of a cut across the
// line the face shares with the table is seen (about half of it), one side, then the other. The base is then
// too large for the area condition; with hidden_min_area_ratio, the hypotheses that place the base with one
// end of its extent along that line at the seen part's end hold the true pose exactly, are marked
// partial_face and come after every fitting one.
TEST(SingleFaceHypotheses, APartlyHiddenFaceIsPlacedByTheEndOfItsView) {
  const PyramidOnItsSide scene(-40.0, 30, -10, 3);
  const fs::host::Library& lib = scene.lib;
  const fs::host::Model& m = lib.models[0];
  const std::size_t base = scene.base;
  const Mat3& R = scene.R;
  const Vec3& t = scene.t;
  PfrgNode face = scene.face;
  fs::Plane table;
  const Vec3 u = face.normal.cross(table.n).normalized();
  double lo = 1e9, hi = -1e9;
  for (const Vec3& v : m.faces[base].loops[0]) {
    lo = std::min(lo, u.dot(R * v + t));
    hi = std::max(hi, u.dot(R * v + t));
  }
  // The seen part: up to the middle of the extent (its area about half the pentagon's), centroid inside it.
  const double cut = 0.5 * (lo + hi);
  face.area = 0.5 * m.faces[base].area;
  face.centroid = R * m.faces[base].centroid + t - 0.25 * (hi - lo) * u;

  auto true_pose_among = [&](std::span<const Hypothesis> hs, bool* partial) {
    for (const Hypothesis& h : hs)
      if (h.model == 0 && fs::host::rec::rotation_angle_deg_sym(R, h.R, m) < 1e-6 &&
          ((R * m.center + t) - (h.R * m.center + h.t)).norm() < 1e-6) {
        *partial = h.partial_face;
        return true;
      }
    return false;
  };
  std::vector<Hypothesis> out(256);
  for (auto& h : out) h.matches.reserve(4);
  fs::host::rec::SingleFaceParams p;
  int n = fs::host::rec::single_face_hypotheses(lib, face, table, p, out);
  bool partial = false;
  for (int k = 0; k < n; ++k) EXPECT_FALSE(out[static_cast<std::size_t>(k)].partial_face);
  EXPECT_FALSE(
      true_pose_among(std::span<const Hypothesis>(out.data(), static_cast<std::size_t>(n)), &partial));

  p.hidden_min_area_ratio = 0.35;
  p.extent_known = true;
  p.extent_min = lo;
  p.extent_max = cut;
  const int fitting = n;
  n = fs::host::rec::single_face_hypotheses(lib, face, table, p, out);
  ASSERT_GT(n, fitting);
  for (int k = 0; k < n; ++k) EXPECT_EQ(out[static_cast<std::size_t>(k)].partial_face, k >= fitting) << k;
  EXPECT_TRUE(
      true_pose_among(std::span<const Hypothesis>(out.data(), static_cast<std::size_t>(n)), &partial));
  EXPECT_TRUE(partial);
  // The other half seen instead: the placement by the other end holds the true pose.
  face.centroid = R * m.faces[base].centroid + t + 0.25 * (hi - lo) * u;
  p.extent_min = cut;
  p.extent_max = hi;
  n = fs::host::rec::single_face_hypotheses(lib, face, table, p, out);
  EXPECT_TRUE(
      true_pose_among(std::span<const Hypothesis>(out.data(), static_cast<std::size_t>(n)), &partial));
  // A view of less than hidden_min_area_ratio of the face is not placed on it.
  face.area = 0.3 * m.faces[base].area;
  n = fs::host::rec::single_face_hypotheses(lib, face, table, p, out);
  EXPECT_FALSE(
      true_pose_among(std::span<const Hypothesis>(out.data(), static_cast<std::size_t>(n)), &partial));
}

}  // namespace

namespace {

// Top-face hypotheses: a box standing on its base, turned 25 deg about the vertical, seen from above so that
// only its top is a region. The turn comes from the top's outline (its convex hull), the height must fit: the
// true pose is among the hypotheses (up to the box's symmetry, centre within 1e-6 mm); a box of another
// height gives none; the hull helper returns the rectangle's 4 corners from a dense sampling of it.
TEST(TopFaceHypotheses, TurnFromTheOutlineAndHeightFromTheTable) {
  fs::host::Library lib;
  lib.add(fs::host::build_model(fs::read_mesh(fs::test::source_dir() / "hw-sim/scenes/meshes/box.off")));
  const fs::host::Model& m = lib.models[0];
  std::size_t top = 0;
  for (std::size_t f = 0; f < m.faces.size(); ++f)
    if (m.faces[f].normal.z() > m.faces[top].normal.z()) top = f;
  ASSERT_GT(m.faces[top].normal.z(), 0.999);  // the mesh stands on z = min, top face up
  double zmin = 1e9;
  for (const auto& f : m.faces)
    for (const Vec3& v : f.loops[0]) zmin = std::min(zmin, v.z());
  const Mat3 R = Eigen::AngleAxisd(25.0 * M_PI / 180.0, Vec3::UnitZ()).toRotationMatrix();
  const Vec3 t(-40, 30, -zmin);
  const fs::Plane table;
  const PfrgNode face = posed_face_node(m, top, R, t, 9);
  const Vec3 u = face.normal.unitOrthogonal(), v = face.normal.cross(u);
  // Dense samples of the top rectangle, then their hull.
  std::vector<Eigen::Vector2d> pts, scratch;
  const auto& loop = m.faces[top].loops[0];
  ASSERT_EQ(loop.size(), 4u);
  for (int i = 0; i <= 40; ++i)
    for (int j = 0; j <= 40; ++j) {
      const Vec3 a = loop[0] + (loop[1] - loop[0]) * (i / 40.0) + (loop[3] - loop[0]) * (j / 40.0);
      const Vec3 w = R * a + t;
      pts.emplace_back(w.dot(u), w.dot(v));
    }
  scratch.reserve(2 * pts.size());
  pts.resize(fs::host::rec::convex_hull_in_place(pts, scratch));
  EXPECT_EQ(pts.size(), 4u);

  std::vector<Hypothesis> out(16);
  const int n = fs::host::rec::top_face_hypotheses(lib, face, table, pts, u, v, {}, out);
  ASSERT_GT(n, 0);
  bool found = false;
  for (int k = 0; k < n; ++k) {
    const Hypothesis& h = out[static_cast<std::size_t>(k)];
    if (fs::host::rec::rotation_angle_deg_sym(R, h.R, m) < 1e-6 &&
        ((R * m.center + t) - (h.R * m.center + h.t)).norm() < 1e-6)
      found = true;
  }
  EXPECT_TRUE(found);
  PfrgNode higher = face;
  higher.offset += 10.0;  // 10 mm higher than the box is tall: no model fits
  higher.centroid.z() += 10.0;
  EXPECT_EQ(fs::host::rec::top_face_hypotheses(lib, higher, table, pts, u, v, {}, out), 0);
}

// A cupola upside down, its largest face on top, resting 30 mm above the table on something unseen: the
// pentagonal one (a decagon, symmetry order 5) and the square one (an octagon, order 4; its symmetries fix
// the octagon's normal only to about 1e-6, the mesh's rounding).
// - On the table no model stands that high: no hypothesis. Raised (TopFaceParams::raised), the cupola's
//   placements rest lower than the face: the true pose is among them, all marked raised and partial_face.
// - A regular n-gon's outline fits n turns equally; on an n/2-fold cupola turns 720/n deg apart are one
//   placement, turns 360/n deg apart are two. The two turns kept are two placements, never one twice:
//   otherwise, as the outline ties, rounding decided whether the true one was kept.
TEST(TopFaceHypotheses, ARaisedTopKeepsDistinctPlacementsOfASymmetricModel) {
  for (const auto& [name, sides] : {std::pair<const char*, std::size_t>{"pentagonal-cupola", 10},
                                    std::pair<const char*, std::size_t>{"square-cupola", 8}}) {
    SCOPED_TRACE(name);
    fs::host::Library lib;
    lib.add(fs::host::build_model(fs::read_mesh(fs::test::shared_data() / "polyhedra/polyhedra-viewer/off" /
                                                (std::string(name) + ".off"))));
    const fs::host::Model& m = lib.models[0];
    ASSERT_EQ(m.symmetry_order(), sides / 2);
    std::size_t top = 0;
    for (std::size_t f = 0; f < m.faces.size(); ++f)
      if (m.faces[f].area > m.faces[top].area) top = f;
    ASSERT_EQ(m.faces[top].loops[0].size(), sides);
    // The top's normal up, turned 20 deg about the vertical; the opposite face 30 mm above the table.
    const Mat3 R = Eigen::AngleAxisd(20.0 * M_PI / 180.0, Vec3::UnitZ()).toRotationMatrix() *
                   Eigen::Quaterniond::FromTwoVectors(m.faces[top].normal, Vec3::UnitZ()).toRotationMatrix();
    double zmin = 1e9;
    for (const auto& f : m.faces)
      for (const Vec3& v : f.loops[0]) zmin = std::min(zmin, (R * v).z());
    const Vec3 t(25, -10, 30.0 - zmin);
    const fs::Plane table;
    const PfrgNode face = posed_face_node(m, top, R, t, 4);
    const Vec3 u = face.normal.unitOrthogonal(), v = face.normal.cross(u);
    std::vector<Eigen::Vector2d> hull;
    for (const Vec3& c : m.faces[top].loops[0]) {
      const Vec3 w = R * c + t;
      hull.emplace_back(w.dot(u), w.dot(v));
    }
    std::vector<Hypothesis> out(16);
    fs::host::rec::TopFaceParams p;
    EXPECT_EQ(fs::host::rec::top_face_hypotheses(lib, face, table, hull, u, v, p, out), 0);
    p.raised = true;
    const int n = fs::host::rec::top_face_hypotheses(lib, face, table, hull, u, v, p, out);
    std::vector<const Hypothesis*> on_top;  // the top's placements (other faces' outlines may fit too)
    bool found = false;
    for (int k = 0; k < n; ++k) {
      const Hypothesis& h = out[static_cast<std::size_t>(k)];
      EXPECT_TRUE(h.raised && h.partial_face);
      if (h.matches[0].ref != static_cast<int>(top)) continue;
      on_top.push_back(&h);
      found = found || (fs::host::rec::rotation_angle_deg_sym(R, h.R, m) < 1e-3 &&
                        ((R * m.center + t) - (h.R * m.center + h.t)).norm() < 1e-3);
    }
    EXPECT_TRUE(found);
    ASSERT_EQ(on_top.size(), static_cast<std::size_t>(p.max_turns));
    EXPECT_NEAR(fs::host::rec::rotation_angle_deg_sym(on_top[0]->R, on_top[1]->R, m), 360.0 / sides, 1e-2);
  }
}

TEST(Report, ResultTableNamesTheAlternativesOfAnObject) {
  fs::host::Library library;
  library.add(cube_model());
  fs::host::Model other = cube_model();
  other.name = "cube-b";
  library.add(std::move(other));
  fs::host::rec::Recognition r;
  r.objects.emplace_back();
  r.objects[0].model = 0;
  r.objects[0].verify.confidence = 1.0;
  const std::string plain = fs::host::rec::result_table(r, library);
  EXPECT_EQ(plain.find("ambiguous"), std::string::npos) << plain;
  r.objects[0].alternatives = 1;
  r.objects[0].alternative[0] = {1, 0.99};
  // Ambiguous: each candidate's confidence is its fit times its share of the fits (1.99 together).
  const std::string table = fs::host::rec::result_table(r, library);
  EXPECT_NE(table.find("ambiguous: cube (0.50, fit 1.00) or cube-b (0.49, fit 0.99)"), std::string::npos)
      << table;
  const nlohmann::json j = fs::host::rec::to_json(r, library);
  ASSERT_TRUE(j["objects"][0].contains("alternatives"));
  EXPECT_EQ(j["objects"][0]["alternatives"][0]["model"], "cube-b");
  EXPECT_DOUBLE_EQ(j["objects"][0]["alternatives"][0]["fit"].get<double>(), 0.99);
  EXPECT_DOUBLE_EQ(j["objects"][0]["alternatives"][0]["confidence"].get<double>(), 0.99 * 0.99 / 1.99);
}

}  // namespace
