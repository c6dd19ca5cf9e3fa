// Catalog entries for closed non-convex solids (polycubes): signed mass properties, resting planes by the
// convex hull of the contact vertices.
#include "hw-sim/scene/polycube_catalog.hpp"

#include <algorithm>
#include <cmath>

#include "common/error.hpp"

namespace fs::sim {
namespace {

double cross2(const Vec2& o, const Vec2& a, const Vec2& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

// Newell normal of face f, unit, pointing out of the solid; zero for a face without area.
Vec3 face_normal(const Mesh& mesh, std::size_t f, bool inward) {
  const auto& face = mesh.faces[f];
  Vec3 n = Vec3::Zero();
  for (std::size_t k = 0; k < face.size(); ++k)
    n += mesh.vertices.at(face[k]).cross(mesh.vertices.at(face[(k + 1) % face.size()]));
  const double len = n.norm();
  if (!(len > 0)) return Vec3::Zero();
  return (inward ? -1.0 : 1.0) * n / len;
}

double largest_extent(const Mesh& m) {
  double d = 0;
  for (std::size_t i = 0; i < m.vertices.size(); ++i)
    for (std::size_t j = i + 1; j < m.vertices.size(); ++j)
      d = std::max(d, (m.vertices[i] - m.vertices[j]).norm());
  return d;
}

}  // namespace

SolidMass solid_mass(const Mesh& mesh) {
  if (mesh.vertices.empty()) throw Error("mesh '" + mesh.name + "': no vertices");
  const Vec3 r = mesh.vertices.front();  // reference point: fewer cancellations than the origin
  double volume = 0;
  Vec3 moment = Vec3::Zero();
  for (const auto& f : mesh.faces)
    for (std::size_t k = 1; k + 1 < f.size(); ++k) {
      const Vec3 a = mesh.vertices.at(f[0]) - r;
      const Vec3 b = mesh.vertices.at(f[k]) - r;
      const Vec3 c = mesh.vertices.at(f[k + 1]) - r;
      const double v = a.dot(b.cross(c)) / 6.0;
      volume += v;
      moment += v * (a + b + c) / 4.0;
    }
  const double extent = largest_extent(mesh);
  if (!(std::abs(volume) > 1e-12 * extent * extent * extent))
    throw Error("mesh '" + mesh.name + "': no volume (closed and consistently wound?)");
  SolidMass m;
  m.inward = volume < 0;
  m.volume = std::abs(volume);
  m.centroid = r + moment / volume;
  return m;
}

std::vector<int> stable_resting_faces(const Mesh& mesh, const SolidMass& mass, double margin_mm) {
  const double tol = 1e-7 * std::max(largest_extent(mesh), 1e-9);
  std::vector<int> out;
  std::vector<Vec3> planes;  // normals of the supporting planes seen
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const Vec3 n = face_normal(mesh, f, mass.inward);
    if (n.isZero() || mesh.faces[f].empty()) continue;
    const Vec3& p0 = mesh.vertices.at(mesh.faces[f][0]);
    bool supporting = true;
    for (const auto& v : mesh.vertices) supporting = supporting && n.dot(v - p0) <= tol;
    if (!supporting) continue;
    if (std::any_of(planes.begin(), planes.end(), [&](const Vec3& m) { return m.dot(n) > 1 - 1e-9; }))
      continue;  // a face of a plane already tried
    planes.push_back(n);
    // The solid rests on the convex hull of its vertices in the plane.
    const Vec3 u = n.unitOrthogonal(), w = n.cross(u);
    std::vector<Vec2> contact;
    for (const auto& v : mesh.vertices)
      if (std::abs(n.dot(v - p0)) <= tol) contact.emplace_back(u.dot(v), w.dot(v));
    const std::vector<Vec2> hull = convex_hull(std::move(contact));
    if (hull.size() < 3) continue;
    const Vec2 c(u.dot(mass.centroid), w.dot(mass.centroid));
    bool inside = true;
    for (std::size_t i = 0; i < hull.size() && inside; ++i) {
      const Vec2& a = hull[i];
      const Vec2& b = hull[(i + 1) % hull.size()];
      inside = cross2(a, b, c) / (b - a).norm() > margin_mm;
    }
    if (inside) out.push_back(static_cast<int>(f));
  }
  return out;
}

std::vector<CatalogEntry> make_polycube_catalog(const std::vector<Mesh>& meshes, double margin_mm) {
  std::vector<CatalogEntry> out;
  out.reserve(meshes.size());
  for (const auto& m : meshes) {
    CatalogEntry e;
    e.mesh = m;
    e.size_mm = largest_extent(m);
    const SolidMass mass = solid_mass(m);
    e.centroid = mass.centroid;
    e.stable_faces = stable_resting_faces(m, mass, margin_mm);
    if (e.stable_faces.empty()) throw Error("mesh '" + m.name + "': no stable resting plane");
    out.push_back(std::move(e));
  }
  return out;
}

}  // namespace fs::sim
