#pragma once
// Checks of matcher solutions against the known pose of a test view (up to the model's symmetry).
#include <cmath>
#include <map>
#include <vector>

#include "host/match/inexact.hpp"
#include "host/match/rotation_fit.hpp"
#include "test_graphs.hpp"

namespace fs::test {

struct Verdict {
  bool equivalent = false;  // rotation = R_true * S for a symmetry S of the model, matches consistent
  double rotation_error_deg = 1e9;
  int wrong_matches = 0;
};

// `orig` maps scene node ids to the model face they come from (identity unless split/spurious faces).
// The symmetry is found from the solution's rotation: S0 = R_true^T R maps every model face onto the face
// whose normal is nearest (within 25 deg, equal area within 1 %); S = the exact rotation of that face map
// (Kabsch) must then map every normal onto its partner within 0.5 deg, i.e. be a symmetry of the model. Noise
// in R (a few degrees with perturbed normals) thus does not hide a correct correspondence; the rotation error
// is measured against R_true * S.
inline Verdict judge(const host::Pfrg& model, const Mat3& R_true, const host::match::Solution& sol,
                     const std::map<int, int>& orig = {}) {
  Verdict v;
  const Mat3 S0 = R_true.transpose() * sol.rotation;  // candidate symmetry
  std::map<int, int> face_map;                        // model face i -> face j with S n_i = n_j
  std::vector<Vec3> a, b;
  std::vector<double> w;
  for (const auto& ni : model.nodes) {
    if (ni.supernode) continue;
    int best = -1;
    double best_ang = 25.0;
    for (const auto& nj : model.nodes) {
      if (nj.supernode) continue;
      const double ang =
          std::acos(std::clamp((S0 * ni.normal).dot(nj.normal), -1.0, 1.0)) * 180 / std::numbers::pi;
      if (ang < best_ang && std::abs(ni.area - nj.area) <= 0.01 * std::max(ni.area, nj.area)) {
        best = nj.id;
        best_ang = ang;
      }
    }
    if (best < 0) return v;
    face_map[ni.id] = best;
    a.push_back(ni.normal);
    b.push_back(model.find(best)->normal);
    w.push_back(1.0);
  }
  const Mat3 S_exact = host::match::kabsch_rotation(a, b, w);
  for (std::size_t i = 0; i < a.size(); ++i)
    if (std::acos(std::clamp((S_exact * a[i]).dot(b[i]), -1.0, 1.0)) * 180 / std::numbers::pi > 0.5) return v;
  for (const auto& m : sol.matches) {
    auto it = orig.find(m.scene);
    const int src = it == orig.end() ? m.scene : it->second;
    if (face_map[m.ref] != src) ++v.wrong_matches;
  }
  v.equivalent = v.wrong_matches == 0;
  v.rotation_error_deg = host::match::rotation_angle_deg(sol.rotation, R_true * S_exact);
  return v;
}

}  // namespace fs::test
