#pragma once
// Synthetic organized grids for the segmentation tests and benchmark: convex polyhedra (half-space sets)
// standing on the table z = 0, seen by a pinhole camera above the table (world frame of common/calibration:
// z up toward the sensor). Each cell gets the true 3D point (plus optional Gaussian noise along the ray),
// the object id (0 = table) and a ground-truth face label object * 100 + face.
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "common/calibration.hpp"
#include "host/io/organized_cloud.hpp"

namespace fs::test {

struct ConvexObject {
  std::vector<fs::Plane> planes;  // outward normals; the solid is { x : n.x <= d for all planes }
};

inline ConvexObject make_box(const fs::Vec3& centre, const fs::Vec3& half, double yaw_deg) {
  const double a = yaw_deg * 3.14159265358979323846 / 180.0;
  const fs::Mat3 R = Eigen::AngleAxisd(a, fs::Vec3::UnitZ()).toRotationMatrix();
  ConvexObject o;
  for (int ax = 0; ax < 3; ++ax) {
    for (int sgn : {1, -1}) {
      fs::Plane p;
      p.n = R.col(ax) * double(sgn);
      p.d = p.n.dot(centre) + half[ax];
      o.planes.push_back(p);
    }
  }
  return o;
}

// Square pyramid on the table: base half-width b, height h, apex above centre.
inline ConvexObject make_pyramid(const fs::Vec3& base_centre, double b, double h, double yaw_deg) {
  const double a = yaw_deg * 3.14159265358979323846 / 180.0;
  const fs::Mat3 R = Eigen::AngleAxisd(a, fs::Vec3::UnitZ()).toRotationMatrix();
  ConvexObject o;
  fs::Plane base;
  base.n = -fs::Vec3::UnitZ();
  base.d = -base_centre.z();
  o.planes.push_back(base);
  const fs::Vec3 apex = base_centre + fs::Vec3(0, 0, h);
  for (int k = 0; k < 4; ++k) {
    const double phi = k * 3.14159265358979323846 / 2;
    const fs::Vec3 out = R * fs::Vec3(std::cos(phi), std::sin(phi), 0);
    fs::Vec3 n = (out * h + fs::Vec3::UnitZ() * b).normalized();
    fs::Plane p;
    p.n = n;
    p.d = n.dot(apex);
    o.planes.push_back(p);
  }
  return o;
}

struct SyntheticScene {
  std::vector<ConvexObject> objects;  // object k has id k + 1; the table is object 0 (plane z = 0)
  fs::Vec3 camera{0, 0, 500};
  double focal = 400;  // pixels
  std::uint32_t width = 240, height = 200;
  double table_half = 140;  // table extent (|x|, |y| <= table_half), NaN beyond
};

struct SyntheticGrid {
  fs::host::OrganizedCloud cloud;
  std::vector<std::int32_t> face;    // object * 100 + face index (table = 0), -1 = no data
  std::vector<std::int32_t> object;  // 0 = table, k = object k, -1 = no data
  std::vector<fs::Vec3> true_points;
};

inline void render(const SyntheticScene& sc, SyntheticGrid& g, double noise_mm = 0.0, unsigned seed = 1) {
  g.cloud.reset(sc.width, sc.height);
  g.cloud.viewpoint = sc.camera;
  const std::size_t n = std::size_t(sc.width) * sc.height;
  g.face.assign(n, -1);
  g.object.assign(n, -1);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  g.true_points.assign(n, fs::Vec3(nan, nan, nan));
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, noise_mm);
  for (std::uint32_t r = 0; r < sc.height; ++r) {
    for (std::uint32_t c = 0; c < sc.width; ++c) {
      const fs::Vec3 dir =
          fs::Vec3((c - 0.5 * (sc.width - 1)) / sc.focal, (r - 0.5 * (sc.height - 1)) / sc.focal, -1)
              .normalized();
      double best = std::numeric_limits<double>::infinity();
      int bobj = -1, bface = -1;
      if (dir.z() < 0) {
        const double t = -sc.camera.z() / dir.z();
        const fs::Vec3 p = sc.camera + t * dir;
        if (std::abs(p.x()) <= sc.table_half && std::abs(p.y()) <= sc.table_half) {
          best = t;
          bobj = 0;
          bface = 0;
        }
      }
      for (std::size_t k = 0; k < sc.objects.size(); ++k) {
        double t0 = 0, t1 = std::numeric_limits<double>::infinity();
        int entry = -1;
        bool hit = true;
        for (std::size_t f = 0; f < sc.objects[k].planes.size() && hit; ++f) {
          const auto& pl = sc.objects[k].planes[f];
          const double dn = pl.n.dot(dir), num = pl.d - pl.n.dot(sc.camera);
          if (std::abs(dn) < 1e-12) {
            if (num < 0) hit = false;
            continue;
          }
          const double t = num / dn;
          if (dn < 0) {
            if (t > t0) {
              t0 = t;
              entry = int(f);
            }
          } else {
            t1 = std::min(t1, t);
          }
          if (t0 > t1) hit = false;
        }
        if (hit && entry >= 0 && t0 < best) {
          best = t0;
          bobj = int(k) + 1;
          bface = entry;
        }
      }
      if (bobj < 0) continue;
      const std::size_t i = std::size_t(r) * sc.width + c;
      const fs::Vec3 p = sc.camera + best * dir;
      g.true_points[i] = p;
      g.cloud.points[i] = (p + (noise_mm > 0 ? gauss(rng) : 0.0) * dir).cast<float>();
      g.object[i] = bobj;
      g.face[i] = bobj * 100 + bface;
    }
  }
}

}  // namespace fs::test
