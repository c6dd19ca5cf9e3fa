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
  bool equivalent = false;       // rotation = R_true * S for a symmetry S of the model, matches consistent
  double rotation_error_deg = 1e9;
  int wrong_matches = 0;
};

// `orig` maps scene node ids to the model face they come from (identity unless split/spurious faces).
inline Verdict judge(const host::Pfrg& model, const Mat3& R_true, const host::match::Solution& sol,
                     const std::map<int, int>& orig = {}) {
  Verdict v;
  const Mat3 S = R_true.transpose() * sol.rotation;   // candidate symmetry
  std::map<int, int> face_map;                        // model face i -> face j with S n_i = n_j
  std::vector<Vec3> a, b;
  std::vector<double> w;
  for (const auto& ni : model.nodes) {
    int best = -1;
    for (const auto& nj : model.nodes) {
      const double ang = std::acos(std::clamp((S * ni.normal).dot(nj.normal), -1.0, 1.0)) * 180 / std::numbers::pi;
      if (ang < 5.0 && std::abs(ni.area - nj.area) <= 0.01 * std::max(ni.area, nj.area)) best = nj.id;
    }
    if (best < 0) return v;
    face_map[ni.id] = best;
    a.push_back(ni.normal);
    b.push_back(model.find(best)->normal);
    w.push_back(1.0);
  }
  const Mat3 S_exact = host::match::kabsch_rotation(a, b, w);
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
