#pragma once
// Internal to the segmenter (host/segment/*.cpp, one file per stage; see README.md): the per-cell state bits,
// the continuity bits and the small grid helpers the stages share. Not part of the public interface
// (segmenter.hpp).
#include <cmath>
#include <cstddef>
#include <cstdint>

#include <Eigen/Core>

#include "host/segment/grid_kernels.hpp"

namespace fs::host::seg::detail {

constexpr std::int32_t kUnassigned = -3;
constexpr std::uint8_t kValid = 1, kHasNormal = 2, kSeed = 4, kTried = 8, kQueued = 16;
// continuity bits (cont_): cell i is depth-continuous toward its left / right / upper / lower neighbour
using kernels::kContD;
using kernels::kContL;
using kernels::kContR;
using kernels::kContU;
constexpr double kPi = 3.14159265358979323846;

// Points with any non-finite coordinate carry no data (NaN = no data by contract; inf is treated alike).
inline bool finite(const Eigen::Vector3f& p) { return p.allFinite() && p.cwiseAbs().maxCoeff() < 1e7f; }

inline double cos_deg(double deg) { return std::cos(deg * kPi / 180.0); }

inline std::uint64_t pair_key(std::int32_t a, std::int32_t b) {
  return (std::uint64_t(std::uint32_t(a)) << 32) | std::uint32_t(b);
}

inline std::size_t next_pow2(std::size_t v) {
  std::size_t p = 1;
  while (p < v) p <<= 1;
  return p;
}

// The 4-neighbours of cell i in a w x h grid and their continuity bits (kContL/R/U/D); returns how many.
inline int grid_neighbours(std::size_t i, std::size_t w, std::size_t h, std::size_t nb[4],
                           std::uint8_t bit[4]) {
  const std::size_t row = i / w, col = i - row * w;
  int k = 0;
  if (col > 0) {
    nb[k] = i - 1;
    bit[k++] = kContL;
  }
  if (col + 1 < w) {
    nb[k] = i + 1;
    bit[k++] = kContR;
  }
  if (row > 0) {
    nb[k] = i - w;
    bit[k++] = kContU;
  }
  if (row + 1 < h) {
    nb[k] = i + w;
    bit[k++] = kContD;
  }
  return k;
}

}  // namespace fs::host::seg::detail
