#include "hw-sim/scene/random_scene.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Geometry>

#include "common/error.hpp"
#include "hw-sim/scene/cluttered_scene.hpp"
#include "hw-sim/scene/prng.hpp"

namespace fs::sim {

namespace {

double cross2(const Vec2& o, const Vec2& a, const Vec2& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

bool separated_on_axis(const std::vector<Vec2>& a, const std::vector<Vec2>& b, const Vec2& axis) {
  double amin = 1e300, amax = -1e300, bmin = 1e300, bmax = -1e300;
  for (const auto& p : a) amin = std::min(amin, axis.dot(p)), amax = std::max(amax, axis.dot(p));
  for (const auto& p : b) bmin = std::min(bmin, axis.dot(p)), bmax = std::max(bmax, axis.dot(p));
  return amax < bmin || bmax < amin;
}

bool overlap(const std::vector<Vec2>& a, const std::vector<Vec2>& b) {
  for (const auto* poly : {&a, &b})
    for (std::size_t i = 0; i < poly->size(); ++i) {
      const Vec2 e = (*poly)[(i + 1) % poly->size()] - (*poly)[i];
      if (separated_on_axis(a, b, Vec2(-e.y(), e.x()))) return false;
    }
  return true;
}

double point_segment(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 ab = b - a;
  const double len2 = ab.squaredNorm();
  const double s = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + s * ab - p).norm();
}

double max_extent(const Mesh& m) {
  double d = 0;
  for (std::size_t i = 0; i < m.vertices.size(); ++i)
    for (std::size_t j = i + 1; j < m.vertices.size(); ++j)
      d = std::max(d, (m.vertices[i] - m.vertices[j]).norm());
  return d;
}

// A posed candidate: rotation, footprint at the origin (xy) and the lift that puts it on the table.
struct Posed {
  Mat3 R = Mat3::Identity();
  double z = 0;
  std::vector<Vec2> hull;  // footprint with translation (0, 0)
  Vec2 lo, hi;             // its bounding box
  double radius = 0;       // max |hull point|
};

Posed pose_mesh(const Mesh& mesh, const Vec3& down_normal, double yaw) {
  Posed p;
  const Mat3 align = Eigen::Quaterniond::FromTwoVectors(down_normal, Vec3(0, 0, -1)).toRotationMatrix();
  p.R = Eigen::AngleAxisd(yaw, Vec3::UnitZ()).toRotationMatrix() * align;
  double zmin = 1e300;
  std::vector<Vec2> pts;
  pts.reserve(mesh.vertices.size());
  for (const auto& v : mesh.vertices) {
    const Vec3 x = p.R * v;
    zmin = std::min(zmin, x.z());
    pts.emplace_back(x.x(), x.y());
  }
  p.z = -zmin;
  p.hull = convex_hull(std::move(pts));
  p.lo = Vec2(1e300, 1e300);
  p.hi = -p.lo;
  for (const auto& q : p.hull) {
    p.lo = p.lo.cwiseMin(q);
    p.hi = p.hi.cwiseMax(q);
    p.radius = std::max(p.radius, q.norm());
  }
  return p;
}

std::vector<Vec2> shifted(const std::vector<Vec2>& hull, const Vec2& t) {
  std::vector<Vec2> out(hull);
  for (auto& q : out) q += t;
  return out;
}

Mesh make_box(double a, double b, double c) {
  Mesh m;
  m.name = "distractor-box";
  for (int i = 0; i < 8; ++i)
    m.vertices.emplace_back((i & 1 ? 0.5 : -0.5) * a, (i & 2 ? 0.5 : -0.5) * b, (i & 4 ? 0.5 : -0.5) * c);
  m.faces = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  return m;
}

struct Placer {
  const RandomSceneOptions& o;
  Prng& rng;
  std::vector<std::vector<Vec2>> placed;

  double uniform(double a, double b) { return a + (b - a) * rng.uniform(); }

  bool inside(const Posed& p, const Vec2& t) const {
    return t.x() + p.lo.x() >= o.x_min && t.x() + p.hi.x() <= o.x_max && t.y() + p.lo.y() >= o.y_min &&
           t.y() + p.hi.y() <= o.y_max;
  }
  bool fits_rect(const Posed& p) const {
    return p.hi.x() - p.lo.x() <= o.x_max - o.x_min && p.hi.y() - p.lo.y() <= o.y_max - o.y_min;
  }
  Vec2 random_position(const Posed& p) {
    return Vec2(uniform(o.x_min - p.lo.x(), o.x_max - p.hi.x()),
                uniform(o.y_min - p.lo.y(), o.y_max - p.hi.y()));
  }
  double min_distance(const std::vector<Vec2>& h) const {
    double d = 1e300;
    for (const auto& q : placed) d = std::min(d, polygon_distance(h, q));
    return d;
  }
  // A position where p's footprint is `gap` away from placed[anchor], in direction `dir` from its centre.
  Vec2 touching_position(const Posed& p, std::size_t anchor, const Vec2& dir, double gap) const {
    Vec2 c = Vec2::Zero();
    for (const auto& q : placed[anchor]) c += q;
    c /= static_cast<double>(placed[anchor].size());
    double anchor_r = 0;
    for (const auto& q : placed[anchor]) anchor_r = std::max(anchor_r, (q - c).norm());
    double lo = 0, hi = anchor_r + p.radius + gap + 1.0;
    for (int it = 0; it < 40; ++it) {
      const double mid = 0.5 * (lo + hi);
      if (polygon_distance(shifted(p.hull, c + mid * dir), placed[anchor]) < gap)
        lo = mid;
      else
        hi = mid;
    }
    return c + hi * dir;
  }
};

}  // namespace

std::vector<Vec2> convex_hull(std::vector<Vec2> p) {
  std::sort(p.begin(), p.end(),
            [](const Vec2& a, const Vec2& b) { return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y()); });
  if (p.size() < 3) return p;
  std::vector<Vec2> h(2 * p.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross2(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (std::size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross2(h[k - 2], h[k - 1], p[i - 1]) <= 0) --k;
    h[k++] = p[i - 1];
  }
  h.resize(k - 1);
  return h;
}

const char* to_string(SceneCategory c) {
  switch (c) {
    case SceneCategory::single:
      return "single";
    case SceneCategory::separated:
      return "separated";
    case SceneCategory::occluded:
      return "occluded";
    case SceneCategory::empty:
      return "empty";
    case SceneCategory::cluttered:
      return "cluttered";
  }
  return "?";
}

SceneCategory parse_scene_category(const std::string& name) {
  for (auto c : {SceneCategory::single, SceneCategory::separated, SceneCategory::occluded,
                 SceneCategory::empty, SceneCategory::cluttered})
    if (name == to_string(c)) return c;
  throw Error("scene category '" + name + "': expected single, separated, occluded, empty or cluttered");
}

std::vector<Mesh> read_catalog_meshes(const std::filesystem::path& dir) {
  std::vector<std::filesystem::path> files;
  if (!std::filesystem::is_directory(dir)) throw Error(dir.string() + ": not a directory");
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.path().extension() == ".off") files.push_back(e.path());
  if (files.empty()) throw Error(dir.string() + ": no .off meshes");
  std::sort(files.begin(), files.end());
  std::vector<Mesh> meshes;
  meshes.reserve(files.size());
  for (const auto& f : files) meshes.push_back(read_mesh(f));
  return meshes;
}

namespace {

// Volume and first moment, by tetrahedra from an interior point (any face winding).
double volume_and_moment(const Mesh& mesh, Vec3& moment) {
  Vec3 interior = Vec3::Zero();
  for (const auto& v : mesh.vertices) interior += v;
  interior /= static_cast<double>(std::max<std::size_t>(1, mesh.vertices.size()));
  double volume = 0;
  moment = Vec3::Zero();
  for (const auto& f : mesh.faces)
    for (std::size_t k = 1; k + 1 < f.size(); ++k) {
      const Vec3& a = mesh.vertices.at(f[0]);
      const Vec3& b = mesh.vertices.at(f[k]);
      const Vec3& c = mesh.vertices.at(f[k + 1]);
      const double v = std::abs((a - interior).dot((b - interior).cross(c - interior))) / 6.0;
      volume += v;
      moment += v * (interior + a + b + c) / 4.0;
    }
  if (!(volume > 0)) throw Error("mesh '" + mesh.name + "': no volume");
  return volume;
}

}  // namespace

double mesh_volume(const Mesh& mesh) {
  Vec3 moment;
  return volume_and_moment(mesh, moment);
}

Vec3 volume_centroid(const Mesh& mesh) {
  Vec3 moment;
  const double volume = volume_and_moment(mesh, moment);
  return moment / volume;
}

Vec3 outward_normal(const Mesh& mesh, std::size_t face, const Vec3& interior_point) {
  const auto& f = mesh.faces.at(face);
  Vec3 n = Vec3::Zero();
  Vec3 c = Vec3::Zero();
  for (std::size_t k = 0; k < f.size(); ++k) {
    const Vec3& a = mesh.vertices.at(f[k]);
    n += a.cross(mesh.vertices.at(f[(k + 1) % f.size()]));
    c += a;
  }
  c /= static_cast<double>(f.size());
  if (n.norm() == 0) throw Error("mesh '" + mesh.name + "': face " + std::to_string(face) + " has no area");
  n.normalize();
  return n.dot(c - interior_point) < 0 ? Vec3(-n) : n;
}

bool is_stable_face(const Mesh& mesh, std::size_t face, const Vec3& centroid, double margin_mm) {
  const Vec3 n = outward_normal(mesh, face, centroid);
  const auto& f = mesh.faces.at(face);
  const Vec3& a0 = mesh.vertices.at(f[0]);
  const Vec3 p = centroid - n * n.dot(centroid - a0);  // projection on the face plane
  // Inside a convex polygon: on the inner side of every edge (edges oriented counter-clockwise about n).
  double sign = 0;
  for (std::size_t k = 0; k < f.size(); ++k) {
    const Vec3& a = mesh.vertices.at(f[k]);
    const Vec3& b = mesh.vertices.at(f[(k + 1) % f.size()]);
    const Vec3 e = b - a;
    const double len = e.norm();
    if (len == 0) continue;
    const double s = n.dot(e.cross(p - a)) / len;  // signed distance of p from the edge line
    if (sign == 0) sign = s >= 0 ? 1 : -1;
    if (s * sign <= margin_mm) return false;
  }
  return true;
}

std::vector<CatalogEntry> make_catalog(const std::vector<Mesh>& meshes, const CatalogOptions& options) {
  Prng rng(options.seed);
  std::vector<CatalogEntry> out;
  out.reserve(meshes.size());
  for (const auto& m : meshes) {
    CatalogEntry e;
    e.mesh = m;
    const double extent = max_extent(m);
    if (!(extent > 0)) throw Error("mesh '" + m.name + "': no extent");
    e.size_mm = options.min_size_mm + (options.max_size_mm - options.min_size_mm) * rng.uniform();
    for (auto& v : e.mesh.vertices) v *= e.size_mm / extent;
    e.centroid = volume_centroid(e.mesh);
    e.volume_mm3 = mesh_volume(e.mesh);
    for (std::size_t f = 0; f < e.mesh.faces.size(); ++f)
      if (is_stable_face(e.mesh, f, e.centroid, 0.5)) e.stable_faces.push_back(static_cast<int>(f));
    if (e.stable_faces.empty()) throw Error("mesh '" + m.name + "': no stable resting face");
    out.push_back(std::move(e));
  }
  return out;
}

std::vector<Vec2> footprint(const SceneObject& object) {
  std::vector<Vec2> pts;
  for (const auto& f : object.faces)
    for (const auto& x : f.polygon) pts.emplace_back(x.x(), x.y());
  return convex_hull(std::move(pts));
}

double polygon_distance(const std::vector<Vec2>& a, const std::vector<Vec2>& b) {
  if (a.empty() || b.empty()) return 1e300;
  if (overlap(a, b)) return 0.0;
  double d = 1e300;
  for (const auto* p : {&a, &b}) {
    const auto& q = p == &a ? b : a;
    for (const auto& v : *p)
      for (std::size_t i = 0; i < q.size(); ++i)
        d = std::min(d, point_segment(v, q[i], q[(i + 1) % q.size()]));
  }
  return d;
}

RandomScene make_random_scene(const std::vector<CatalogEntry>& catalog, const RandomSceneOptions& o,
                              std::uint64_t seed) {
  if (catalog.empty() && o.category != SceneCategory::empty) throw Error("random scene: empty catalog");
  if (o.min_objects < 1 || o.max_objects < o.min_objects)
    throw Error("random scene: need 1 <= min_objects <= max_objects");
  if (o.clutter_min_objects < 1 || o.clutter_max_objects < o.clutter_min_objects)
    throw Error("random scene: need 1 <= clutter_min_objects <= clutter_max_objects");
  Prng rng(seed * 0x9E3779B97F4A7C15ULL + 0x5EED + static_cast<std::uint64_t>(o.category));
  for (int restart = 0; restart < 64; ++restart) {
    RandomScene out;
    out.category = o.category;
    out.scene.calibration = ScannerCalibration::bench_default();
    if (o.steps != out.scene.calibration.step_count) resample_sweep(out.scene.calibration, o.steps);
    out.scene.source = std::string("random-") + to_string(o.category) + "-" + std::to_string(seed);
    Placer placer{o, rng, {}};
    const double yaw_range = 2.0 * std::numbers::pi;

    if (o.category == SceneCategory::empty) {
      if (rng.uniform() < 0.5) return out;  // an empty table
      // A flat box: proportions far from a cube, so no catalog solid explains it.
      const Mesh box = make_box(placer.uniform(50, 75), placer.uniform(22, 35), placer.uniform(8, 18));
      const Posed p = pose_mesh(box, Vec3(0, 0, -1), placer.uniform(0, yaw_range));
      const Vec2 t = placer.random_position(p);
      add_object(out.scene, box, p.R, Vec3(t.x(), t.y(), p.z));
      out.catalog_index.push_back(-1);
      out.resting_face.push_back(-1);
      out.support.push_back(-1);
      out.support_face.push_back(-1);
      return out;
    }
    if (o.category == SceneCategory::cluttered) {
      if (place_cluttered(catalog, o, rng, out)) return out;
      continue;
    }

    const int want =
        o.category == SceneCategory::single
            ? 1
            : o.min_objects +
                  static_cast<int>(rng.below(static_cast<std::uint64_t>(o.max_objects - o.min_objects + 1)));
    for (int i = 0; i < want; ++i) {
      bool ok = false;
      for (int attempt = 0; attempt < 60 && !ok; ++attempt) {
        const int ci = static_cast<int>(rng.below(catalog.size()));
        const CatalogEntry& e = catalog[static_cast<std::size_t>(ci)];
        const int face = e.stable_faces[rng.below(e.stable_faces.size())];
        const Vec3 n = outward_normal(e.mesh, static_cast<std::size_t>(face), e.centroid);
        const Posed p = pose_mesh(e.mesh, n, placer.uniform(0, yaw_range));
        if (!placer.fits_rect(p)) continue;
        Vec2 t;
        if (placer.placed.empty() || o.category == SceneCategory::single) {
          t = placer.random_position(p);
        } else if (o.category == SceneCategory::separated) {
          t = placer.random_position(p);
          if (placer.min_distance(shifted(p.hull, t)) < o.separation_mm) continue;
        } else {  // occluded: next to an already placed object
          const std::size_t anchor = rng.below(placer.placed.size());
          const double a = placer.uniform(0, yaw_range);
          const double gap = placer.uniform(o.touch_gap_min_mm, o.touch_gap_max_mm);
          t = placer.touching_position(p, anchor, Vec2(std::cos(a), std::sin(a)), gap);
          if (!placer.inside(p, t)) continue;
          if (placer.min_distance(shifted(p.hull, t)) < o.touch_gap_min_mm) continue;
        }
        if (!placer.inside(p, t)) continue;
        add_object(out.scene, e.mesh, p.R, Vec3(t.x(), t.y(), p.z));
        out.catalog_index.push_back(ci);
        out.resting_face.push_back(face);
        out.support.push_back(-1);
        out.support_face.push_back(-1);
        placer.placed.push_back(shifted(p.hull, t));
        ok = true;
      }
      if (!ok) break;
    }
    const int min_needed = o.category == SceneCategory::single ? 1 : std::min(o.min_objects, want);
    if (static_cast<int>(out.scene.objects.size()) >= min_needed) return out;
  }
  throw Error(std::string("random scene (") + to_string(o.category) + ", seed " + std::to_string(seed) +
              "): could not place the objects in the rectangle");
}

}  // namespace fs::sim
