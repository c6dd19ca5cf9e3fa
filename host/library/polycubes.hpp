#pragma once
// Artificial reference objects glued from unit cubes (thesis ch. 4.1.3): every polycube of volume 1..N
// exactly once up to rotation and translation (mirror images are distinct), as cell sets, surface meshes and
// models (coplanar unit squares merged into faces).
#include <array>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/mesh.hpp"
#include "host/library/model.hpp"

namespace fs::host {

using Cell = std::array<int, 3>;
using Polycube =
    std::vector<Cell>;  // canonical: sorted cells, translated to min 0, least over the 24 rotations

// The 24 proper rotations of the cube lattice (signed permutation matrices with determinant +1).
const std::array<Mat3, 24>& cube_rotations();

// Canonical form of a face-connected cell set (the test of preexistence: equal canonical forms <=> same
// object up to rotation and translation).
Polycube canonical_polycube(const Polycube& cells);

// Number of the 24 rotations mapping the cell set onto itself (up to translation).
int polycube_symmetry_order(const Polycube& cells);

// All polycubes by volume: result[v - 1] lists those of volume v in ascending canonical order. Grows each
// volume v-1 object by one face-adjacent cube. max_volume in [1, 10]; throws fs::Error otherwise.
std::vector<std::vector<Polycube>> enumerate_polycubes(int max_volume);

// Boundary surface: one outward quad per exposed unit-cube side, edge length `edge` (mm).
Mesh polycube_mesh(const Polycube& cells, double edge, const std::string& name);

// "polycube-<volume>-<index, 3 digits, from 1>".
std::string polycube_name(int volume, std::size_t index);

// The model of a polycube (build_model on polycube_mesh).
Model polycube_model(const Polycube& cells, double edge, const std::string& name);

// The models of every polycube of `all` (enumerate_polycubes), volume by volume, named by polycube_name: what
// `facetscan library polycubes` writes. `before(done, name)`, when given, is called before each model is
// built.
std::vector<Model> polycube_models(const std::vector<std::vector<Polycube>>& all, double edge,
                                   const std::function<void(std::size_t, const std::string&)>& before = {});

// (volume, index from 1) of a name "polycube-<volume>-<index>"; nullopt for any other name.
struct PolycubeId {
  int volume = 0;
  std::size_t index = 0;
};
std::optional<PolycubeId> parse_polycube_name(std::string_view name);

// The surface mesh of a library's polycube model (as `library polycubes` made it): the cells of its name in
// `generated` (enumerate_polycubes of at least its volume), the edge from its bounding box, in the model's
// frame (placing the mesh at (R, t) places the model there). Throws fs::Error naming `source` and
// the model when the name is no polycube's, lies beyond `generated`, or the mesh does not reproduce the model
// (area, volume, bounding box).
Mesh polycube_mesh_of(const Model& model, const std::vector<std::vector<Polycube>>& generated,
                      const std::string& source);

}  // namespace fs::host
