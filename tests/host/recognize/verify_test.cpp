// Unit tests of the verification geometry (host/recognize/verify.hpp): ray casting against a model in its own
// frame, on a convex model (the cube: the first front face containing the hit ends the search) and on a
// non-convex one (a U-shaped prism: a ray crosses two front faces and the nearer one must win).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "common/mesh.hpp"
#include "host/io/organized_cloud.hpp"
#include "host/library/model.hpp"
#include "host/recognize/verify.hpp"
#include "support/polyhedra_catalog.hpp"
#include "support/test_paths.hpp"

namespace {

using fs::Vec3;

// The polygon (x, z) extruded over y in [-h, h]; the polygon is counter-clockwise seen from -y.
fs::Mesh extrude_xz(const std::vector<std::pair<double, double>>& poly, double h) {
  fs::Mesh m;
  m.name = "extruded";
  const auto n = static_cast<std::uint32_t>(poly.size());
  for (const auto& [x, z] : poly) m.vertices.emplace_back(x, -h, z);
  for (const auto& [x, z] : poly) m.vertices.emplace_back(x, h, z);
  std::vector<std::uint32_t> front, back;
  for (std::uint32_t i = 0; i < n; ++i) {
    front.push_back(i);             // y = -h, normal -y: counter-clockwise seen from -y
    back.push_back(2 * n - 1 - i);  // y = +h, normal +y: reversed
  }
  m.faces.push_back(front);
  m.faces.push_back(back);
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t j = (i + 1) % n;
    m.faces.push_back({j, i, n + i, n + j});
  }
  return m;
}

TEST(ModelGeometry, ConvexCubeRayEntersThroughTheFaceItHits) {
  const fs::host::Model cube =
      fs::host::build_model(fs::read_mesh(fs::test::source_dir() / "hw-sim/scenes/meshes/cube.off"));
  const fs::host::rec::ModelGeometry g(cube);
  EXPECT_TRUE(g.convex());
  // Straight down onto the centre, and a slanted ray: both must hit the face whose plane they cross first
  // while inside its outline, at the plane distance.
  for (const Vec3& dir : {Vec3(0, 0, -1), Vec3(0.2, -0.1, -1).normalized()}) {
    const Vec3 origin = cube.center - 300.0 * dir;
    double s = 0.0;
    const int face = g.cast(origin, dir, s);
    ASSERT_GE(face, 0);
    const fs::host::ModelFace& f = cube.faces[static_cast<std::size_t>(face)];
    EXPECT_LT(f.normal.dot(dir), 0.0);
    EXPECT_NEAR(f.normal.dot(origin + s * dir), f.offset, 1e-9);
    // No other face plane is crossed earlier inside the solid: the hit point lies on the surface.
    for (const fs::host::ModelFace& o : cube.faces)
      EXPECT_LE(o.normal.dot(origin + s * dir), o.offset + 1e-9);
  }
  double s = 0.0;
  EXPECT_EQ(g.cast(cube.center + Vec3(0, 0, 300), Vec3(1, 0, 0), s), -1);  // passes above
}

// The half-space clip of a convex model (cast_convex, what verification uses for convex models) gives the hit
// of the polygon test (cast) on every one of the 120 polyhedra: rays from all around aimed near the model,
// many missing it. They may differ only where a ray passes within a hair of an edge.
TEST(ModelGeometry, ConvexClipGivesThePolygonTestsHitOnEveryPolyhedron) {
  const auto& lib = fs::test::polyhedra_catalog().library;
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  fs::host::rec::ClipFaces clip;
  int hits = 0, misses = 0, compared = 0, other_face = 0;
  for (const fs::host::Model& model : lib.models) {
    const fs::host::rec::ModelGeometry g(model);
    ASSERT_TRUE(g.convex()) << model.name;
    for (int k = 0; k < 400; ++k) {
      const Vec3 origin = model.center + 4.0 * model.bounding_radius *
                                             Vec3(normal(rng), normal(rng), normal(rng)).normalized();
      const Vec3 aim =
          model.center + 1.2 * model.bounding_radius * Vec3(normal(rng), normal(rng), normal(rng)) / 2.0;
      const Vec3 dir = (aim - origin).normalized();
      g.clip_faces(origin, clip);
      double s_poly = 0.0, s_clip = 0.0;
      const int f_poly = g.cast(origin, dir, s_poly);
      const int f_clip = g.cast_convex(origin, dir, s_clip, clip);
      ++compared;
      if (f_poly < 0 && f_clip < 0) {
        ++misses;
        continue;
      }
      ASSERT_GE(f_poly, 0) << model.name << " ray " << k << ": the clip hits at " << s_clip;
      ASSERT_GE(f_clip, 0) << model.name << " ray " << k << ": the polygon test hits at " << s_poly;
      ++hits;
      // Equal distances put the hit on both faces' planes: different faces only where it lies on an edge.
      EXPECT_NEAR(s_clip, s_poly, 1e-6) << model.name << " ray " << k;
      other_face += f_clip != f_poly ? 1 : 0;
    }
  }
  EXPECT_EQ(compared, 400 * static_cast<int>(lib.models.size()));
  EXPECT_LT(other_face, hits / 1000 + 1);  // random rays hit an edge next to never
  EXPECT_GT(hits, compared / 4);           // both outcomes well represented
  EXPECT_GT(misses, compared / 10);
  // From inside the model nothing is hit (the verifier's sensor never is inside: evaluate() returns first).
  const fs::host::rec::ModelGeometry g(lib.models.front());
  g.clip_faces(lib.models.front().center, clip);
  double s = 0.0;
  EXPECT_EQ(g.cast_convex(lib.models.front().center, Vec3(0, 0, 1), s, clip), -1);
}

// The clip four faces at a time (convex_clip.hpp) returns bit for bit what the face-by-face loop did: the
// same face (the first of equal entries), the same distance, the same misses. Rays from outside and from
// inside, rays parallel to face planes (grazing, inside and outside them), through vertices (equal entries of
// several faces), and face counts that are not a multiple of the lanes.
namespace {

struct FaceColumns {
  const double *nx, *ny, *nz, *h;  // unit normals, heights n . origin - offset
};

int clip_face_by_face(const FaceColumns& f, std::size_t faces, const Vec3& dir, double& distance) {
  distance = std::numeric_limits<double>::infinity();
  int best = -1;
  double enter = 0.0, leave = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < faces; ++i) {
    const double den = f.nx[i] * dir.x() + f.ny[i] * dir.y() + f.nz[i] * dir.z();
    const double h = f.h[i];
    if (den < -1e-9) {
      const double s = -h / den;
      if (s > enter) enter = s, best = static_cast<int>(i);
    } else if (den > 1e-9) {
      leave = std::min(leave, -h / den);
    } else if (h > 0.0) {
      return -1;
    }
    if (enter > leave) return -1;
  }
  if (best < 0) return -1;
  distance = enter;
  return best;
}

}  // namespace

TEST(ConvexClip, FourOrEightFacesAtATimeEqualTheFaceByFaceLoopBitForBit) {
  const auto& lib = fs::test::polyhedra_catalog().library;
  std::mt19937_64 rng(11);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_int_distribution<int> pick(0, 5);
  int compared = 0, hits = 0, grazing = 0, vertex = 0, compared_avx512 = 0;
  std::vector<double> nx, ny, nz, h;
  fs::host::rec::ClipFaces clip;
  for (const fs::host::Model& model : lib.models) {
    const std::size_t n = model.faces.size();
    nx.assign(n, 0.0), ny.assign(n, 0.0), nz.assign(n, 0.0), h.assign(n, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3 nn = model.faces[i].normal.normalized();
      nx[i] = nn.x(), ny[i] = nn.y(), nz[i] = nn.z();
    }
    for (int k = 0; k < 300; ++k) {
      const int kind = pick(rng);
      Vec3 origin = model.center +
                    4.0 * model.bounding_radius * Vec3(normal(rng), normal(rng), normal(rng)).normalized();
      if (kind == 5) origin = model.center + 0.2 * model.bounding_radius * Vec3(normal(rng), 0.0, 0.0);
      Vec3 aim = model.center + 0.6 * model.bounding_radius * Vec3(normal(rng), normal(rng), normal(rng));
      const fs::host::ModelFace& face = model.faces[static_cast<std::size_t>(k) % n];
      if (kind == 3) aim = face.loops.front().front();  // a vertex: several faces enter at once
      Vec3 dir = (aim - origin).normalized();
      if (kind == 4) {  // parallel to a face plane
        const Vec3 nn = face.normal.normalized();
        dir = (dir - dir.dot(nn) * nn).normalized();
        ++grazing;
      }
      vertex += kind == 3 ? 1 : 0;
      for (std::size_t i = 0; i < n; ++i)
        h[i] = model.faces[i].normal.normalized().dot(origin) - model.faces[i].offset;
      const FaceColumns f{nx.data(), ny.data(), nz.data(), h.data()};
      clip.clear();
      for (std::size_t i = 0; i < n; ++i) clip.add(nx[i], ny[i], nz[i], h[i], static_cast<int>(i));
      clip.pad(fs::host::rec::kClipLanes);  // four lanes first; eight (a multiple of four) for AVX-512 below
      double s_ref = 0.0, s_clip = 0.0;
      const int f_ref = clip_face_by_face(f, n, dir, s_ref);
      const int f_clip = fs::host::rec::clip_convex_portable(clip, dir.x(), dir.y(), dir.z(), s_clip);
      ASSERT_EQ(f_clip, f_ref) << model.name << " ray " << k << " kind " << kind;
      if (f_ref >= 0) {
        ASSERT_EQ(s_clip, s_ref) << model.name << " ray " << k;  // bit for bit
        ++hits;
      }
#if defined(__x86_64__)
      if (fs::host::rec::clip_convex_has_avx2()) {
        double s_avx = 0.0;
        ASSERT_EQ(fs::host::rec::clip_convex_avx2(clip, dir.x(), dir.y(), dir.z(), s_avx), f_ref)
            << model.name << " ray " << k << " kind " << kind;
        if (f_ref >= 0) {
          ASSERT_EQ(s_avx, s_ref) << model.name << " ray " << k;
        }
      }
      if (fs::host::rec::clip_convex_has_avx512()) {
        clip.pad(fs::host::rec::kClipMaxLanes);
        double s_avx = 0.0;
        ASSERT_EQ(fs::host::rec::clip_convex_avx512(clip, dir.x(), dir.y(), dir.z(), s_avx), f_ref)
            << model.name << " ray " << k << " kind " << kind;
        if (f_ref >= 0) {
          ASSERT_EQ(s_avx, s_ref) << model.name << " ray " << k;
        }
        ++compared_avx512;
      }
#endif
      ++compared;
    }
  }
  EXPECT_GT(hits, compared / 4);
  EXPECT_LT(hits, compared * 3 / 4);
  if (fs::host::rec::clip_convex_has_avx512()) {
    EXPECT_EQ(compared_avx512, compared);
  }
  EXPECT_GT(grazing, compared / 10);
  EXPECT_GT(vertex, compared / 10);
}

// The rules on their own, on the box [-10, 10]^3: exactly equal entries through two front faces; a ray
// parallel to a face plane on the plane (not outside it: no miss) and just outside it (a miss); a ray whose
// exit through a back face equals its entry (through the edge of a front and a back face, where the clip
// divides to decide), each as the face-by-face loop decides it.
TEST(ConvexClip, EqualEntriesGiveTheFirstFaceAndARayOnAFacePlaneIsNoMiss) {
  // Faces: 0 +z, 1 -z, 2 -x, 3 +x, 4 +y, 5 -y.
  const double nx[6] = {0, 0, -1, 1, 0, 0}, ny[6] = {0, 0, 0, 0, 1, -1}, nz[6] = {1, -1, 0, 0, 0, 0};
  double h[6];
  fs::host::rec::ClipFaces clip;
  const auto run = [&](const Vec3& origin, const Vec3& dir, double& s) {
    clip.clear();
    for (int i = 0; i < 6; ++i) {
      h[i] = Vec3(nx[i], ny[i], nz[i]).dot(origin) - 10.0;
      clip.add(nx[i], ny[i], nz[i], h[i], i);
    }
    clip.pad(fs::host::rec::kClipLanes);
    double s_ref = 0.0;
    const int f_ref = clip_face_by_face(FaceColumns{nx, ny, nz, h}, 6, dir, s_ref);
    const int f_clip = fs::host::rec::clip_convex_portable(clip, dir.x(), dir.y(), dir.z(), s);
    EXPECT_EQ(f_clip, f_ref);
#if defined(__x86_64__)
    if (fs::host::rec::clip_convex_has_avx2()) {
      double s_avx = 0.0;
      EXPECT_EQ(fs::host::rec::clip_convex_avx2(clip, dir.x(), dir.y(), dir.z(), s_avx), f_clip);
      EXPECT_EQ(s_avx, s);
    }
    if (fs::host::rec::clip_convex_has_avx512()) {
      clip.pad(fs::host::rec::kClipMaxLanes);
      double s_avx = 0.0;
      EXPECT_EQ(fs::host::rec::clip_convex_avx512(clip, dir.x(), dir.y(), dir.z(), s_avx), f_clip);
      EXPECT_EQ(s_avx, s);
    }
#endif
    return f_clip;
  };
  double s = 0.0;
  // Through the edge of +x (face 3) and +y (face 4): both enter at 10 sqrt(2).
  EXPECT_EQ(run(Vec3(20, 20, 0), Vec3(-1, -1, 0).normalized(), s), 3);
  EXPECT_NEAR(s, 10.0 * std::sqrt(2.0), 1e-12);
  // Through the edge of +z (face 0) and +y (face 4).
  EXPECT_EQ(run(Vec3(0, 20, 20), Vec3(0, -1, -1).normalized(), s), 0);
  // Along the plane of +x from a point on it: grazing inside the half-space closure, so it enters +y at 10.
  EXPECT_EQ(run(Vec3(10, 20, 0), Vec3(0, -1, 0), s), 4);
  EXPECT_EQ(s, 10.0);
  // The same just outside the plane: a miss.
  EXPECT_EQ(run(Vec3(10.001, 20, 0), Vec3(0, -1, 0), s), -1);
  // Leaving through -y before entering +x: a miss; from inside: a miss.
  EXPECT_EQ(run(Vec3(30, -5, 0), Vec3(-1, -2, 0).normalized(), s), -1);
  EXPECT_EQ(run(Vec3(0, 0, 0), Vec3(1, 0, 0), s), -1);
  // Into +x (a front face) exactly at its edge with +z (a back face: the origin is below its plane), and the
  // same ray a hair lower (a hit) and higher (it leaves through +z before it enters: a miss).
  for (const double dz : {0.0, 1e-9, 5e-13, -5e-13, -1e-9}) {
    const Vec3 origin(20, 0, 5);
    const int f = run(origin, (Vec3(10, 0, 10 - dz) - origin).normalized(), s);
    if (dz > 1e-10) {
      EXPECT_EQ(f, 3) << dz;
    } else if (dz < -1e-10) {
      EXPECT_EQ(f, -1) << dz;
    }
  }
}

// An open model (a face missing, BuildOptions::allow_open) is no convex solid: verification must not close it
// (the half-space clip would report the missing top's plane as a wall above the box).
TEST(ModelGeometry, AnOpenBoxIsNotClippedAsASolid) {
  fs::Mesh m = fs::read_mesh(fs::test::source_dir() / "hw-sim/scenes/meshes/cube.off");
  std::erase_if(m.faces, [&](const std::vector<std::uint32_t>& f) {
    return std::all_of(f.begin(), f.end(), [&](std::uint32_t v) { return m.vertices[v].z() > 49.0; });
  });
  ASSERT_EQ(m.faces.size(), 5u);
  fs::host::BuildOptions o;
  o.allow_open = true;
  const fs::host::Model box = fs::host::build_model(m, o);
  ASSERT_TRUE(box.open);
  const fs::host::rec::ModelGeometry g(box);
  EXPECT_FALSE(g.convex());
  // From above and to the side, down through the open top onto the inner face of the far wall (x = -25).
  const Vec3 origin(150, 0, 150);
  const Vec3 dir = (Vec3(-25, 0, 25) - origin).normalized();
  double s = 0.0;
  const int face = g.cast(origin, dir, s);
  ASSERT_EQ(face, -1);  // inner faces look away from the ray: nothing is hit in front
  // What the clip would say if the box counted as a solid: a hit in the air above it.
  fs::host::rec::ClipFaces clip;
  g.clip_faces(origin, clip);
  double s_clip = 0.0;
  const int f_clip = g.cast_convex(origin, dir, s_clip, clip);
  ASSERT_GE(f_clip, 0);
  EXPECT_GT((origin + s_clip * dir).z(), 50.0);
}

TEST(ModelGeometry, NonConvexUShapeGivesTheNearestOfTwoFrontFaces) {
  // Two prongs (x in [0, 10] and [40, 50], up to z = 30) on a base (z in [0, 10]).
  const fs::Mesh u =
      extrude_xz({{0, 0}, {50, 0}, {50, 30}, {40, 30}, {40, 10}, {10, 10}, {10, 30}, {0, 30}}, 10);
  const fs::host::Model model = fs::host::build_model(u);
  const fs::host::rec::ModelGeometry g(model);
  EXPECT_FALSE(g.convex());
  // A ray from +x at prong height enters the right prong's outer wall (x = 50) and, past the gap, the left
  // prong's inner wall (x = 10), both facing it: the outer wall is the hit.
  for (const Vec3& dir : {Vec3(-1, 0, 0), Vec3(1, 0, 0)}) {
    const Vec3 origin(dir.x() < 0 ? 100.0 : -50.0, 0.0, 20.0);
    double s = 0.0;
    const int face = g.cast(origin, dir, s);
    ASSERT_GE(face, 0);
    const double x_hit = origin.x() + s * dir.x();
    EXPECT_NEAR(x_hit, dir.x() < 0 ? 50.0 : 0.0, 1e-9);
  }
  // Through the gap from above: the base's top (z = 10) between the prongs.
  double s = 0.0;
  ASSERT_GE(g.cast(Vec3(25, 0, 100), Vec3(0, 0, -1), s), 0);
  EXPECT_NEAR(s, 90.0, 1e-9);
  // The U-shaped end faces are non-convex polygons: a ray along -y through the gap misses them (and the
  // solid), one through a prong or the base hits the end face at y = +10.
  EXPECT_EQ(g.cast(Vec3(25, 100, 20), Vec3(0, -1, 0), s), -1);
  for (const Vec3& at : {Vec3(5, 100, 20), Vec3(45, 100, 25), Vec3(25, 100, 5)}) {
    ASSERT_GE(g.cast(at, Vec3(0, -1, 0), s), 0) << at.transpose();
    EXPECT_NEAR(s, 90.0, 1e-9);
  }
  // The front-face list from one origin gives the same hits as all faces.
  const auto& geo = g;
  std::vector<std::uint32_t> front;
  const Vec3 origin(80, 60, 70);
  geo.front_faces(origin, front);
  EXPECT_LT(front.size(), model.faces.size());
  for (int k = 0; k < 200; ++k) {
    const Vec3 target(0.25 * k, 10.0 * std::sin(k), 15.0 + 10.0 * std::cos(0.7 * k));
    const Vec3 dir = (target - origin).normalized();
    double s_all = 0.0, s_front = 0.0;
    const int f_all = geo.cast(origin, dir, s_all);
    EXPECT_EQ(geo.cast(origin, dir, s_front, front), f_all);
    if (f_all >= 0) {
      EXPECT_DOUBLE_EQ(s_front, s_all);
    }
  }
}

TEST(SampleSet, StepsFollowTheGridSpacingInMillimetres) {
  // A flat organized grid 0.5 mm apart along the rows and 0.25 mm along the columns, seen from 500 mm above.
  fs::host::OrganizedCloud cloud;
  cloud.reset(200, 400);
  for (std::uint32_t r = 0; r < cloud.height; ++r)
    for (std::uint32_t c = 0; c < cloud.width; ++c)
      cloud.at(r, c) = Eigen::Vector3f(0.5f * c, 0.25f * r, 0.0f);
  cloud.viewpoint = Vec3(50, 50, 500);
  const Eigen::Vector2d g = fs::host::rec::grid_spacing_mm(cloud);
  EXPECT_NEAR(g.x(), 0.5, 1e-5);
  EXPECT_NEAR(g.y(), 0.25, 1e-5);
  using fs::host::rec::sample_steps;
  fs::host::rec::SampleSet set;
  const auto fine = sample_steps(g, 2, 1.5);
  EXPECT_EQ(fine.col, 3u);
  EXPECT_EQ(fine.row, 6u);
  set.build(cloud, fine);
  EXPECT_EQ(set.points().size(), std::size_t((200 + 2) / 3) * std::size_t((400 + 5) / 6));
  const auto every2 = sample_steps(g, 2, 0.0);  // off: every 2nd row and column
  EXPECT_EQ(every2.col, 2u);
  EXPECT_EQ(every2.row, 2u);
  set.build(cloud, every2);
  EXPECT_EQ(set.points().size(), std::size_t(100 * 200));
  const auto dense = sample_steps(g, 4, 0.5);  // never denser than sample_step
  EXPECT_EQ(dense.col, 4u);
  EXPECT_EQ(dense.row, 4u);
  cloud.organized = false;  // no grid neighbourhood: sample_step only
  EXPECT_EQ(fs::host::rec::grid_spacing_mm(cloud), Eigen::Vector2d::Zero());
  EXPECT_EQ(sample_steps(fs::host::rec::grid_spacing_mm(cloud), 2, 1.5).col, 2u);
}

// A cube and the table around it, scanned: rays from a sensor in front and above through a grid on the table
// (z = 0), onto the cube (resting on z = 0, centred on x = y = 0: the model frame) or the table; samples
// every second cell, about 1.5 mm apart.
// A scan from `sensor` of the table x in [-60, -60 + 0.75 (width - 1)], y in [-80, 79] (160 rows): each
// cell's range along its ray to the table is what range_of(ray direction, range to the table) returns.
template <class RangeOf>
fs::host::OrganizedCloud table_scan(const Vec3& sensor, std::uint32_t width, RangeOf range_of) {
  fs::host::OrganizedCloud cloud;
  cloud.reset(width, 160);
  for (std::uint32_t r = 0; r < cloud.height; ++r)
    for (std::uint32_t c = 0; c < cloud.width; ++c) {
      const Vec3 on_table(-60.0 + 0.75 * c, -80.0 + 1.0 * r, 0.0);
      const Vec3 dir = (on_table - sensor).normalized();
      cloud.at(r, c) = Vec3(sensor + range_of(dir, (on_table - sensor).norm()) * dir).cast<float>();
    }
  cloud.viewpoint = sensor;
  return cloud;
}

class CubeScan : public ::testing::Test {
 protected:
  CubeScan() {
    const Vec3 sensor(0, -250, 250);
    const auto cloud = table_scan(sensor, 160, [&](const Vec3& dir, double range) {
      double s = 0.0;
      return g.cast(sensor, dir, s) >= 0 ? s : range;
    });
    samples.build(cloud, fs::host::rec::sample_steps(fs::host::rec::grid_spacing_mm(cloud), 2, 1.5));
    v.reserve(samples.points().size(), cube.faces.size());
  }
  const fs::host::Model cube =
      fs::host::build_model(fs::read_mesh(fs::test::source_dir() / "hw-sim/scenes/meshes/cube.off"));
  const fs::host::rec::ModelGeometry g{cube};
  fs::host::rec::SampleSet samples;
  fs::host::rec::Verifier v;
};

// check_above (reseat's placements): the same result as verify() without refinement when the fit beats the
// floor; 0 when it does not, and then it stops before the last sample once the samples left cannot lift it
// (it casts fewer rays: fewer hits than the whole check).
TEST_F(CubeScan, CheckAboveGivesTheFitAboveTheFloorAndStopsEarlyBelow) {
  // Raised 12 mm and turned 20 degrees: most rays that meet it end on the table or the cube behind it.
  const fs::Mat3 turned = Eigen::AngleAxisd(20.0 * M_PI / 180.0, Vec3::UnitZ()).toRotationMatrix();
  const std::pair<fs::Mat3, Vec3> poses[] = {{fs::Mat3::Identity(), Vec3::Zero()}, {turned, Vec3(0, 0, 12)}};
  int stopped = 0;
  for (const auto& [R0, t0] : poses) {
    fs::Mat3 R = R0;
    Vec3 t = t0;
    const auto whole = v.verify(samples, g, R, t, false);
    ASSERT_GT(whole.hits, 200);
    const auto above = v.check_above(samples, g, R0, t0, whole.confidence - 0.01);
    EXPECT_EQ(above.confidence, whole.confidence);
    EXPECT_EQ(above.inliers, whole.inliers);
    EXPECT_EQ(above.violations, whole.violations);
    EXPECT_EQ(above.occluded, whole.occluded);
    const auto below = v.check_above(samples, g, R0, t0, whole.confidence);  // not above: equal
    EXPECT_EQ(below.confidence, 0.0);
    if (whole.confidence < 0.5) {
      const auto early = v.check_above(samples, g, R0, t0, 0.9);
      EXPECT_EQ(early.confidence, 0.0);
      EXPECT_LT(early.hits, whole.hits / 2) << "stopped early";
      ++stopped;
    }
  }
  EXPECT_EQ(stopped, 1);  // the true pose fits, the other does not
}

// A cube seen from the front and above shows two faces: their planes fix y and z of the translation, not x.
// The matcher fills x from the face centroids, which are off when a face is seen only in part; ICP cannot fix
// it either (point-to-plane terms along x are zero). verify_sliding searches along that direction.
TEST_F(CubeScan, SlidingFindsTheTranslationThePlanesLeaveOpen) {
  const fs::Mat3 I = fs::Mat3::Identity();
  const Vec3 off(4.0, 0.0, 0.0);  // the pose 4 mm off along x
  fs::Mat3 R = I;
  Vec3 t = off;
  const auto plain = v.verify(samples, g, R, t, true);
  EXPECT_GT(std::abs(t.x()), 3.0) << "ICP moved along the free direction";
  EXPECT_GT(plain.violations, 20);
  R = I;
  t = off;
  const auto slid = v.verify_sliding(samples, samples, g, R, t, Vec3::UnitX());
  EXPECT_NEAR(t.x(), 0.0, 0.5);
  EXPECT_NEAR(t.y(), 0.0, 0.1);
  EXPECT_NEAR(t.z(), 0.0, 0.1);
  EXPECT_LT(slid.violations, plain.violations / 4);
  EXPECT_GT(slid.confidence, plain.confidence + 0.02);
  // The true pose stays where it is (no gain elsewhere along x).
  R = I;
  t = Vec3::Zero();
  v.verify_sliding(samples, samples, g, R, t, Vec3::UnitX());
  EXPECT_NEAR(t.norm(), 0.0, 1e-6);
}

// Less than a slide step off along the free direction: the rays past the cube's ends see the table where the
// pose claims the cube (violations). The 1 mm and 0.5 mm steps on their own leave the pose 0.2-0.3 mm off;
// the finer steps on the fine samples (slide_fine_mm) bring it to within one of them.
TEST_F(CubeScan, FineSlideStepsPlaceThePoseWithinAFractionOfAMillimetre) {
  const double offsets[] = {0.2, 0.3, -0.3, 0.7};
  for (const double fine : {0.0, 0.0625}) {
    fs::host::rec::VerifyParams p;
    p.slide_fine_mm = fine;
    fs::host::rec::Verifier w(p);
    int left_off = 0;
    for (const double off : offsets) {
      fs::Mat3 R = fs::Mat3::Identity();
      Vec3 t(off, 0.0, 0.0);
      const auto r = w.verify_sliding(samples, samples, g, R, t, Vec3::UnitX());
      left_off += std::abs(t.x()) >= 0.19 ? 1 : 0;
      if (fine > 0.0) {
        EXPECT_LT(std::abs(t.x()), 0.07) << "from " << off;
        EXPECT_EQ(r.violations, 0) << "from " << off;
        EXPECT_NEAR(t.y(), 0.0, 0.01);
        EXPECT_NEAR(t.z(), 0.0, 0.01);
      }
    }
    if (fine == 0.0) {
      EXPECT_EQ(left_off, 4) << "without the fine steps";
    }
  }
}

}  // namespace

// The cube beside a second cube of its height, 8 mm apart along x (the free direction of its two seen
// faces), behind a wall that hides its left part. A pose slid toward the second cube explains the whole
// visible part and some of the second cube's top and front, so more points than the true pose, while the
// rays through the gap see the table where it claims the cube.
class CubeBesideACube : public ::testing::Test {
 protected:
  CubeBesideACube() {
    const Vec3 sensor(0, -250, 250);
    const Vec3 beside(58, 0, 0);
    const auto cloud = table_scan(sensor, 200, [&](const Vec3& dir, double range) {
      double s = 0.0;
      if (g.cast(sensor, dir, s) >= 0) range = std::min(range, s);
      if (g.cast(sensor - beside, dir, s) >= 0) range = std::min(range, s);
      if (wall_g.cast(sensor, dir, s) >= 0) range = std::min(range, s);
      return range;
    });
    samples.build(cloud, fs::host::rec::sample_steps(fs::host::rec::grid_spacing_mm(cloud), 2, 1.5));
  }
  const fs::Mesh cube_mesh = fs::read_mesh(fs::test::source_dir() / "hw-sim/scenes/meshes/cube.off");
  const fs::host::Model cube = fs::host::build_model(cube_mesh);
  const fs::host::rec::ModelGeometry g{cube};
  // The wall: x in [-60, -10], y in [-110, -90], z in [0, 150] (the cube's corners mapped).
  const fs::host::Model wall = fs::host::build_model([this] {
    fs::Mesh m = cube_mesh;
    for (Vec3& p : m.vertices)
      p = Vec3(p.x() < 0 ? -60.0 : -10.0, p.y() < 0 ? -110.0 : -90.0, p.z() > 0 ? 150.0 : 0.0);
    return m;
  }());
  const fs::host::rec::ModelGeometry wall_g{wall};
  fs::host::rec::SampleSet samples;
};

// The slide goes back to the true pose although it explains fewer points there (slide_keep_inliers); asked
// to keep every inlier it stays where the gap's rays see through it.
TEST_F(CubeBesideACube, TheSlideGivesUpPointsItExplainsThroughAGap) {
  const fs::Mat3 I = fs::Mat3::Identity();
  fs::host::rec::Verifier v;
  fs::Mat3 R = I;
  Vec3 t = Vec3::Zero();
  const auto truth = v.verify(samples, g, R, t, false);
  t = Vec3(8.0, 0, 0);
  const auto off = v.verify(samples, g, R, t, false);
  ASSERT_GT(off.inliers, truth.inliers) << "the pose slid toward the second cube explains more points";
  ASSERT_GT(off.violations, 20);
  ASSERT_EQ(truth.violations, 0);
  ASSERT_GT(truth.confidence, off.confidence);
  for (const double keep : {1.0, fs::host::rec::VerifyParams{}.slide_keep_inliers}) {
    fs::host::rec::VerifyParams p;
    p.slide_keep_inliers = keep;
    fs::host::rec::Verifier w(p);
    R = I;
    t = Vec3(8.0, 0, 0);
    const auto slid = w.verify_sliding(samples, samples, g, R, t, Vec3::UnitX());
    if (keep == 1.0) {
      EXPECT_GT(t.x(), 4.0) << "asked to keep every inlier";
    } else {
      EXPECT_NEAR(t.x(), 0.0, 0.1);
      EXPECT_NEAR(t.y(), 0.0, 0.1);
      EXPECT_NEAR(t.z(), 0.0, 0.1);
      EXPECT_EQ(slid.violations, 0);
    }
    // From the true pose nothing draws it toward the second cube.
    R = I;
    t = Vec3::Zero();
    w.verify_sliding(samples, samples, g, R, t, Vec3::UnitX());
    EXPECT_NEAR(t.norm(), 0.0, 1e-6);
  }
}
