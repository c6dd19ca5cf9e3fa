#pragma once
// Benchmark helper: the q-quantile (0..1) of a sample by linear interpolation between order statistics; NaN
// for an empty sample.
#include <algorithm>
#include <cmath>
#include <vector>

namespace fs::test {

inline double quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto i = static_cast<std::size_t>(pos);
  const double f = pos - static_cast<double>(i);
  return i + 1 < v.size() ? v[i] * (1 - f) + v[i + 1] * f : v[i];
}

}  // namespace fs::test
