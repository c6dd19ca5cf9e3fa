// bench_verify: verification's hot loop on convex models.
//  - BM_CastConvex/F: the ray cast alone (ModelGeometry::cast_convex, the clip of convex_clip.hpp) over the
//    polyhedra of at least F faces (0: all 120, 40: the largest); items: rays. Each polyhedron (as the
//    recognition benchmark sizes it, 55-85 mm) seen from 600 mm, a grid 1.5 mm apart over its bounding sphere
//    (the fine samples' spacing), row by row; rays outside the sphere (the grid's corners) cost only its
//    test.
//  - BM_Evaluate/F: Verifier::evaluate (verify() without refinement) of the same polyhedra, each scanned on a
//    table from 565 mm (a grid 0.75 mm apart, fine samples about 1.5 mm apart), in its true pose and moved by
//    2 degrees and 1.5 mm as ICP and the reseat see it; items: evaluations.
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "host/io/organized_cloud.hpp"
#include "host/recognize/convex_clip.hpp"
#include "host/recognize/verify.hpp"
#include "support/polyhedra_catalog.hpp"

namespace {

using fs::Vec3;

struct View {
  const fs::host::rec::ModelGeometry* g;
  Vec3 origin;
  std::vector<Vec3> dirs;
};

const std::vector<View>& views() {
  static const std::vector<fs::host::rec::ModelGeometry> geometry = [] {
    std::vector<fs::host::rec::ModelGeometry> out;
    for (const fs::host::Model& m : fs::test::polyhedra_catalog().library.models) out.emplace_back(m);
    return out;
  }();
  static const std::vector<View> all = [] {
    std::vector<View> out;
    std::mt19937_64 rng(5);
    std::normal_distribution<double> normal(0.0, 1.0);
    for (const fs::host::rec::ModelGeometry& g : geometry) {
      View v{&g, g.center() + 600.0 * Vec3(normal(rng), normal(rng), normal(rng)).normalized(), {}};
      const Vec3 ahead = (g.center() - v.origin).normalized();
      const Vec3 right = ahead.unitOrthogonal(), up = ahead.cross(right);
      const double step = 1.5 / 600.0, span = g.radius() / 600.0;
      for (double b = -span; b <= span; b += step)
        for (double a = -span; a <= span; a += step)
          v.dirs.push_back((ahead + a * right + b * up).normalized());
      out.push_back(std::move(v));
    }
    return out;
  }();
  return all;
}

// The items (View or Scan) whose polyhedron has at least the benchmark argument's faces.
template <class T>
std::vector<const T*> with_faces(const std::vector<T>& all, const benchmark::State& state) {
  std::vector<const T*> out;
  for (const T& x : all)
    if (x.g->model().faces.size() >= static_cast<std::size_t>(state.range(0))) out.push_back(&x);
  return out;
}

void BM_CastConvex(benchmark::State& state) {
  const std::vector<const View*> vs = with_faces(views(), state);
  fs::host::rec::ClipFaces clip;
  clip.reserve(128);
  std::int64_t rays = 0, hits = 0;
  for (auto _ : state) {
    for (const View* v : vs) {
      v->g->clip_faces(v->origin, clip);
      for (const Vec3& d : v->dirs) {
        double s = 0.0;
        const int f = v->g->cast_convex(v->origin, d, s, clip);
        benchmark::DoNotOptimize(s);
        hits += f >= 0 ? 1 : 0;
      }
      rays += static_cast<std::int64_t>(v->dirs.size());
    }
  }
  state.SetItemsProcessed(rays);
  state.counters["hit share"] = static_cast<double>(hits) / static_cast<double>(rays);
}
BENCHMARK(BM_CastConvex)->Arg(0)->Arg(40)->Unit(benchmark::kMillisecond);

struct Scan {
  const fs::host::rec::ModelGeometry* g;
  fs::host::rec::SampleSet samples;
};

const std::vector<Scan>& scans() {
  static const std::vector<Scan> all = [] {
    std::vector<Scan> out;
    for (const View& v : views()) {
      const fs::host::rec::ModelGeometry& g = *v.g;
      double floor = std::numeric_limits<double>::infinity();
      for (const fs::host::ModelFace& f : g.model().faces)
        for (const auto& loop : f.loops)
          for (const Vec3& p : loop) floor = std::min(floor, p.z());
      const Vec3 sensor = g.center() + Vec3(0.0, -400.0, 400.0);
      fs::host::OrganizedCloud cloud;
      const auto cells = static_cast<std::uint32_t>(2.6 * g.radius() / 0.75);
      cloud.reset(cells, cells);
      for (std::uint32_t r = 0; r < cells; ++r)
        for (std::uint32_t c = 0; c < cells; ++c) {
          const Vec3 on_table(g.center().x() - 1.3 * g.radius() + 0.75 * c,
                              g.center().y() - 1.3 * g.radius() + 0.75 * r, floor);
          const Vec3 dir = (on_table - sensor).normalized();
          double s = 0.0;
          cloud.at(r, c) = (g.cast(sensor, dir, s) >= 0 ? Vec3(sensor + s * dir) : on_table).cast<float>();
        }
      cloud.viewpoint = sensor;
      Scan scan{&g, {}};
      scan.samples.build(cloud, fs::host::rec::sample_steps(fs::host::rec::grid_spacing_mm(cloud), 2, 1.5));
      out.push_back(std::move(scan));
    }
    return out;
  }();
  return all;
}

void BM_Evaluate(benchmark::State& state) {
  const std::vector<const Scan*> ss = with_faces(scans(), state);
  fs::host::rec::Verifier v;
  v.reserve(200000, 128);
  const fs::Mat3 turned =
      Eigen::AngleAxisd(2.0 * M_PI / 180.0, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  std::int64_t evaluations = 0, inliers = 0;
  for (auto _ : state) {
    for (const Scan* s : ss) {
      const Vec3 c = s->g->center();
      fs::Mat3 R = fs::Mat3::Identity();
      Vec3 t = Vec3::Zero();
      inliers += v.verify(s->samples, *s->g, R, t, false).inliers;  // evaluate() alone
      R = turned;
      t = c - turned * c + Vec3(1.5, 0, 0);
      inliers += v.verify(s->samples, *s->g, R, t, false).inliers;
      evaluations += 2;
    }
  }
  state.SetItemsProcessed(evaluations);
  state.counters["inliers"] = static_cast<double>(inliers) / static_cast<double>(evaluations);
}
BENCHMARK(BM_Evaluate)->Arg(0)->Arg(40)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
