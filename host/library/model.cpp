// finish_model (graph, volume centroid, totals) and the rotation symmetry group of a model.
#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "host/library/model.hpp"

namespace fs::host {
namespace {

// Faces of equal "signature" (area, perimeter, degree, distance of the centroid from the centre) are the
// only candidates for each other under a symmetry.
struct Signature {
  double area, perimeter, distance;
  int degree;
};

}  // namespace

void finish_model(Model& model, std::vector<PfrgArc> arcs, const BuildOptions& options,
                  bool with_symmetries) {
  model.graph = Pfrg{};
  model.graph.name = model.name;
  model.total_area = 0;
  model.graph.nodes.reserve(model.faces.size());
  for (std::size_t i = 0; i < model.faces.size(); ++i) {
    const ModelFace& f = model.faces[i];
    PfrgNode n;
    n.id = static_cast<int>(i);
    n.area = f.area;
    n.normal = f.normal;
    n.offset = f.offset;
    n.centroid = f.centroid;
    n.has_plane = true;
    model.graph.nodes.push_back(n);
    model.total_area += f.area;
  }
  model.graph.arcs = std::move(arcs);

  // Volume and its centroid from the faces (divergence theorem), relative to a reference point for accuracy.
  Vec3 ref = Vec3::Zero();
  for (const auto& f : model.faces) ref += f.centroid * f.area;
  if (model.total_area > 0) ref /= model.total_area;
  double volume = 0;
  Vec3 moment = Vec3::Zero();
  for (const auto& f : model.faces) {
    volume += (f.offset - f.normal.dot(ref)) * f.area / 3.0;
    Vec3 sq = Vec3::Zero();  // integral of (x - ref)^2 componentwise over the face
    const Vec3 c = f.centroid - ref;
    for (const auto& loop : f.loops)
      for (std::size_t i = 0; i < loop.size(); ++i) {
        const Vec3 a = loop[i] - ref, b = loop[(i + 1) % loop.size()] - ref;
        const double s = 0.5 * f.normal.dot((a - c).cross(b - c));
        const Vec3 m1 = 0.5 * (c + a), m2 = 0.5 * (a + b), m3 = 0.5 * (b + c);
        sq += s / 3.0 * (m1.cwiseProduct(m1) + m2.cwiseProduct(m2) + m3.cwiseProduct(m3));
      }
    moment += 0.5 * f.normal.cwiseProduct(sq);
  }
  if (!model.open && volume > 1e-12 * std::pow(std::max(model.total_area, 1e-300), 1.5)) {
    model.volume = volume;
    model.center = ref + moment / volume;
  } else {
    model.volume = 0;
    model.center = ref;
  }
  model.bounding_radius = 0;
  for (const auto& f : model.faces)
    for (const auto& loop : f.loops)
      for (const auto& p : loop)
        model.bounding_radius = std::max(model.bounding_radius, (p - model.center).norm());
  if (with_symmetries) model.symmetries = compute_symmetries(model, options.symmetry_tolerance);
}

std::vector<Mat3> compute_symmetries(const Model& model, double tol) {
  std::vector<Mat3> group{Mat3::Identity()};
  const std::size_t n = model.faces.size();
  if (n < 2) return group;
  const double L = std::max(model.bounding_radius, 1e-300);
  const double len_tol = tol * L;
  double max_area = 0;
  for (const auto& f : model.faces) max_area = std::max(max_area, f.area);
  const double area_tol = tol * max_area;

  std::map<std::pair<int, int>, double> border;
  std::vector<std::vector<int>> adj(n);
  for (const auto& a : model.graph.arcs) {
    border[{std::min(a.a, a.b), std::max(a.a, a.b)}] = a.border;
    adj[static_cast<std::size_t>(a.a)].push_back(a.b);
    adj[static_cast<std::size_t>(a.b)].push_back(a.a);
  }
  auto border_of = [&](int a, int b) {
    auto it = border.find({std::min(a, b), std::max(a, b)});
    return it == border.end() ? -1.0 : it->second;
  };
  std::vector<Signature> sig(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto& f = model.faces[i];
    sig[i] = {f.area, f.perimeter, (f.centroid - model.center).norm(), static_cast<int>(adj[i].size())};
  }
  auto same = [&](std::size_t i, std::size_t j) {
    return sig[i].degree == sig[j].degree && std::abs(sig[i].area - sig[j].area) <= area_tol &&
           std::abs(sig[i].perimeter - sig[j].perimeter) <= len_tol &&
           std::abs(sig[i].distance - sig[j].distance) <= len_tol;
  };
  std::vector<std::size_t> class_size(n, 0);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) class_size[i] += same(i, j);

  // Reference pair: the face of the rarest class and a neighbour (else any face) not parallel to it.
  std::size_t f0 = 0;
  for (std::size_t i = 1; i < n; ++i)
    if (class_size[i] < class_size[f0]) f0 = i;
  const Vec3 n0 = model.faces[f0].normal;
  std::size_t f1 = n;
  auto consider = [&](std::size_t j) {
    if (std::abs(model.faces[j].normal.dot(n0)) > 1 - 1e-6) return;
    if (f1 == n || class_size[j] < class_size[f1]) f1 = j;
  };
  for (int j : adj[f0]) consider(static_cast<std::size_t>(j));
  if (f1 == n)
    for (std::size_t j = 0; j < n; ++j) consider(j);
  if (f1 == n) return group;  // all normals parallel: no rotation can be pinned down
  auto frame = [](const Vec3& a, const Vec3& b) {
    Mat3 F;
    const Vec3 u = (b - b.dot(a) * a).normalized();
    F.col(0) = a;
    F.col(1) = u;
    F.col(2) = a.cross(u);
    return F;
  };
  const Mat3 Ff = frame(n0, model.faces[f1].normal);
  const double cos01 = n0.dot(model.faces[f1].normal);
  const double b01 = border_of(static_cast<int>(f0), static_cast<int>(f1));

  std::vector<int> perm(n);
  for (std::size_t g0 = 0; g0 < n; ++g0) {
    if (!same(f0, g0)) continue;
    for (std::size_t g1 = 0; g1 < n; ++g1) {
      if (g1 == g0 || !same(f1, g1)) continue;
      const Vec3& m0 = model.faces[g0].normal;
      const Vec3& m1 = model.faces[g1].normal;
      if (std::abs(m0.dot(m1) - cos01) > tol) continue;
      const double b = border_of(static_cast<int>(g0), static_cast<int>(g1));
      if ((b01 < 0) != (b < 0) || (b01 >= 0 && std::abs(b - b01) > len_tol)) continue;
      const Mat3 R = frame(m0, m1) * Ff.transpose();
      bool dup = false;
      for (const auto& S : group) dup = dup || (S - R).norm() < tol;
      if (dup) continue;
      // Every face must map onto a face of the same signature, normal and centroid.
      bool ok = true;
      std::vector<bool> taken(n, false);
      for (std::size_t i = 0; i < n && ok; ++i) {
        const Vec3 rn = R * model.faces[i].normal;
        const Vec3 rc = R * (model.faces[i].centroid - model.center);
        int found = -1;
        for (std::size_t j = 0; j < n; ++j) {
          if (taken[j] || !same(i, j)) continue;
          if ((rn - model.faces[j].normal).norm() > tol) continue;
          if ((rc - (model.faces[j].centroid - model.center)).norm() > len_tol) continue;
          found = static_cast<int>(j);
          break;
        }
        if (found < 0)
          ok = false;
        else {
          perm[i] = found;
          taken[static_cast<std::size_t>(found)] = true;
        }
      }
      for (const auto& a : model.graph.arcs) {
        if (!ok) break;
        const double bb = border_of(perm[static_cast<std::size_t>(a.a)], perm[static_cast<std::size_t>(a.b)]);
        ok = bb >= 0 && std::abs(bb - a.border) <= len_tol;
      }
      if (ok) group.push_back(R);
    }
  }
  return group;
}

std::vector<int> face_orbit_representatives(const Model& model, double tol) {
  const std::size_t n = model.faces.size();
  std::vector<int> rep(n);
  for (std::size_t i = 0; i < n; ++i) rep[i] = static_cast<int>(i);
  const double len_tol = tol * std::max(model.bounding_radius, 1e-300);
  double max_area = 0;
  for (const auto& f : model.faces) max_area = std::max(max_area, f.area);
  const double area_tol = tol * max_area;
  for (std::size_t k = 1; k < model.symmetries.size(); ++k) {
    const Mat3& S = model.symmetries[k];
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3 sn = S * model.faces[i].normal;
      const Vec3 sc = S * (model.faces[i].centroid - model.center);
      for (std::size_t j = 0; j < n; ++j) {
        if ((sn - model.faces[j].normal).norm() > tol) continue;
        if ((sc - (model.faces[j].centroid - model.center)).norm() > len_tol) continue;
        if (std::abs(model.faces[i].area - model.faces[j].area) > area_tol) continue;
        rep[i] = std::min(rep[i], static_cast<int>(j));
        break;
      }
    }
  }
  return rep;
}

}  // namespace fs::host
