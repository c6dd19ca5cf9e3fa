#pragma once
// Internal to the inexact matcher (inexact.cpp, search.cpp, solutions.cpp): a state of the search tree
// (thesis ch. 7.2), its rotation fit data, and the pair hash and dissimilarity they use.
#include <algorithm>
#include <cmath>
#include <cstdint>

#include <Eigen/Core>

#include "common/calibration.hpp"
#include "host/match/node_set.hpp"
#include "host/match/rotation_fit.hpp"

namespace fs::host::match::detail {

inline std::uint64_t pair_key(int r, int s) {
  // splitmix64 of the pair index: order-independent match-set hash = XOR of pair keys (Zobrist hashing).
  std::uint64_t z =
      static_cast<std::uint64_t>(r) * kMaxNodes + static_cast<std::uint64_t>(s) + 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

inline double rel_diss(double a, double b) {
  const double m = std::max(a, b);
  return m > 0 ? std::abs(a - b) / m : 0.0;
}

// Hot fields first (heap keys, tree links, flags), the rotation fit matrices last.
struct State {
  double cost = 0;  // exact when fitted; otherwise a lower bound (see the lazy fits in search.cpp)
  double sum_gamma = 0, d_area = 0, d_border = 0, rotfit = 0;
  double lambda = 0;  // smallest eigenvalue of B: lower bound of the children's
  std::uint64_t hash = 0;
  int parent = -1, child_index = 0, level = 0, r = -1, s = -1;
  int am = 0, ai = 0, ad = 0, children = 0, first_r = -1;
  bool expanded = false, degenerate = true;
  bool fitted = true;      // R, q, lambda, rotfit and cost are final
  NodeSet cr, cs, tr, ts;  // core / terminal sets (reference, scene); rest = complement
};

// The rotation fit data of a state, kept apart from State so that the tree walks, duplicate tests and heap
// keys touch less memory.
struct FitData {
  Mat4 B = Mat4::Zero();          // accumulated sum gamma A (7.5.8)
  Mat3 R = Mat3::Identity();      // best fitting rotation
  Eigen::Vector4d q{0, 0, 0, 1};  // its quaternion (x y z w): warm start of the children's fits
};

}  // namespace fs::host::match::detail
