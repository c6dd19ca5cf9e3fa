#pragma once
// Scenes of bench_library_scale: the same scans recognized against libraries of different sizes. A scene is
// its ground-truth cloud (kept: every library sees the same points) and its true objects by model name.
//   polyhedra: random scenes of the 120 polyhedra (make_catalog, as bench_recognition)
//   polycubes: single polycubes from a .fslib (the generator's mesh of each model, make_polycube_catalog),
//              kept when the scan sees at least `min_faces` of the model's faces with `min_face_cells` points
#include <cmath>
#include <cstdint>
#include <map>
#include <string>
#include <unordered_map>
#include <vector>

#include "common/error.hpp"
#include "host/io/organized_cloud.hpp"
#include "host/library/library.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/random_scene.hpp"

namespace fs::bench {

struct TrueObject {
  std::string model;  // "" = not a library object (the box of an empty scene)
  Mat3 R = Mat3::Identity();
  Vec3 t = Vec3::Zero();
};

struct BenchScene {
  std::uint64_t seed = 0;
  sim::SceneCategory category = sim::SceneCategory::single;
  std::vector<TrueObject> objects;
  int faces_seen = 0;  // polycube scenes: model faces seen (>= min_face_cells points)
  host::OrganizedCloud cloud;
  Plane table;
};

inline BenchScene capture(const sim::RandomScene& rs, const std::vector<sim::CatalogEntry>& catalog,
                          std::uint64_t seed, double noise_mm, sim::GroundTruthGrid* grid_out = nullptr) {
  BenchScene s;
  s.seed = seed;
  s.category = rs.category;
  for (std::size_t i = 0; i < rs.scene.objects.size(); ++i) {
    const auto& o = rs.scene.objects[i];
    const int ci = rs.catalog_index[i];
    s.objects.push_back({ci < 0 ? std::string() : catalog[static_cast<std::size_t>(ci)].mesh.name, o.rotation,
                         o.translation});
  }
  sim::GroundTruthGrid grid =
      sim::make_ground_truth_grid(rs.scene, {.depth_noise_mm = noise_mm, .seed = seed});
  grid.export_to(s.cloud, false);
  s.table = rs.scene.calibration.table;
  if (grid_out) *grid_out = std::move(grid);
  return s;
}

// True when p (on the plane of face f) lies inside the face: even-odd over all its loops (holes included).
inline bool inside_face(const host::ModelFace& f, const Vec3& p) {
  const Vec3 u = f.normal.unitOrthogonal(), w = f.normal.cross(u);
  const double px = u.dot(p), py = w.dot(p);
  bool in = false;
  for (const auto& loop : f.loops)
    for (std::size_t i = 0, j = loop.size() - 1; i < loop.size(); j = i++) {
      const double xi = u.dot(loop[i]), yi = w.dot(loop[i]), xj = u.dot(loop[j]), yj = w.dot(loop[j]);
      if ((yi > py) != (yj > py) && px < (xj - xi) * (py - yi) / (yj - yi) + xi) in = !in;
    }
  return in;
}

// Model faces of scene object `object` (index) seen by at least min_cells ground-truth points: the mesh
// quads (the grid's face ids) mapped onto the model's faces by plane and containment.
inline int faces_seen(const sim::GroundTruthGrid& grid, const sim::SceneObject& obj, int object,
                      const host::Model& model, std::size_t min_cells) {
  std::map<int, std::size_t> per_quad;
  for (const auto& c : grid.cells())
    if (c.object == object + 1) ++per_quad[c.face];
  std::map<std::size_t, std::size_t> per_face;
  for (const auto& [q, n] : per_quad) {
    const auto& quad = obj.mesh.faces.at(static_cast<std::size_t>(q));
    Vec3 c = Vec3::Zero(), nrm = Vec3::Zero();
    for (std::size_t k = 0; k < quad.size(); ++k) {
      c += obj.mesh.vertices[quad[k]];
      nrm += obj.mesh.vertices[quad[k]].cross(obj.mesh.vertices[quad[(k + 1) % quad.size()]]);
    }
    c /= static_cast<double>(quad.size());
    nrm.normalize();
    for (std::size_t f = 0; f < model.faces.size(); ++f) {
      const auto& mf = model.faces[f];
      if (mf.normal.dot(nrm) > 0.999 &&
          std::abs(mf.normal.dot(c) - mf.offset) < 1e-6 * model.bounding_radius && inside_face(mf, c)) {
        per_face[f] += n;
        break;
      }
    }
  }
  int seen = 0;
  for (const auto& [f, n] : per_face) seen += n >= min_cells ? 1 : 0;
  return seen;
}

// Single polycubes of `catalog` (the models of `lib` by name) drawn with seeds first_seed, first_seed + 1,
// ...: the first `count` whose scan sees at least min_faces of the model's faces with min_face_cells points
// each. *tried counts the draws; more than 50 per scene is an error.
inline std::vector<BenchScene> polycube_scenes(const host::Library& lib,
                                               const std::vector<sim::CatalogEntry>& catalog, int count,
                                               std::uint64_t first_seed, std::uint32_t steps, double noise,
                                               int min_faces, std::size_t min_face_cells,
                                               int* tried = nullptr) {
  std::unordered_map<std::string, std::size_t> index;
  for (std::size_t i = 0; i < lib.models.size(); ++i) index[lib.models[i].name] = i;
  std::vector<BenchScene> out;
  int draws = 0;
  for (std::uint64_t seed = first_seed; static_cast<int>(out.size()) < count; ++seed) {
    if (++draws > 50 * count) throw Error("polycube scenes: too few seen with enough faces");
    const auto rs =
        sim::make_random_scene(catalog, {.category = sim::SceneCategory::single, .steps = steps}, seed);
    sim::GroundTruthGrid grid;
    BenchScene s = capture(rs, catalog, seed, noise, &grid);
    const auto& model = lib.models[index.at(s.objects.at(0).model)];
    s.faces_seen = faces_seen(grid, rs.scene.objects[0], 0, model, min_face_cells);
    if (s.faces_seen >= min_faces) out.push_back(std::move(s));
  }
  if (tried) *tried = draws;
  return out;
}

}  // namespace fs::bench
