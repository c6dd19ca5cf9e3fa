#pragma once
// Near symmetries of a model (beyond the thesis): rigid motions of the model frame, x -> S x + u, that map
// most of the model's surface onto itself face by face (same shape, plane and place) without being one of its
// symmetries. The gyrate rhombicosidodecahedron has 5 rotation symmetries, but each of the
// rhombicosidodecahedron's 60 rotations maps all of it except the gyrated cupola (and where it lands) onto
// itself. A view of the mapped part matches such a model in several placements that agree on every matched
// face; the search keeps a few of them, and only verification against the points where the placements
// differ tells them apart. The recognizer therefore verifies the near-symmetric placements of each plausible
// hypothesis of such a model (reseat.cpp).
#include <vector>

#include "host/library/model.hpp"

namespace fs::host::rec {

struct NearSymmetry {
  Mat3 S = Mat3::Identity();
  Vec3 u = Vec3::Zero();
  double share = 0.0;         // share of the model's area on faces mapped onto faces
  std::vector<int> preimage;  // by face f: the face the motion maps onto f, -1 when none does
};

struct NearSymmetryParams {
  double min_share = 0.4;   // of the model's area (RecognizeParams::near_symmetry_share)
  double tolerance = 5e-3;  // relative: lengths / bounding radius, areas / largest face; normals in rad
  int seeds = 4;            // reference face pairs spread over the model (farthest faces first)
  int max_count = 64;
};

// The near symmetries of `model`, one per placement class: two motions that differ by a symmetry of the
// model give equivalent poses and only the first is kept. Empty for a model of fewer than 4 faces.
std::vector<NearSymmetry> near_symmetries(const Model& model, const NearSymmetryParams& p = {});

// Moves pose (R, t) of a model to its placement by the near symmetry T: (R S, R u + t); model face i then
// lies where face T(i) lay.
inline void apply_near_symmetry(const NearSymmetry& T, Mat3& R, Vec3& t) {
  t += R * T.u;
  R = R * T.S;
}

}  // namespace fs::host::rec
