#include "firmware/loop/lateness_histogram.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

namespace fs::fw {

int LatenessHistogram::bucket(std::uint64_t v) {
  if (v < kSub) return static_cast<int>(v);
  const int msb = 63 - std::countl_zero(v);  // >= 4
  const int sub = static_cast<int>((v >> (msb - 4)) & (kSub - 1));
  return std::min(kBuckets - 1, (msb - 3) * kSub + sub);
}

std::int64_t LatenessHistogram::upper(int b) {
  if (b < kSub) return b;
  const int msb = b / kSub + 3;
  const std::uint64_t base = 1ull << msb;
  const std::uint64_t width = 1ull << (msb - 4);
  return static_cast<std::int64_t>(base + (static_cast<std::uint64_t>(b % kSub) + 1) * width - 1);
}

void LatenessHistogram::add(std::int64_t ns) {
  if (ns < 0) ns = 0;  // early wake-ups count as on time
  if (count_ == 0) min_ = max_ = ns;
  min_ = std::min(min_, ns);
  max_ = std::max(max_, ns);
  ++count_;
  ++n_[static_cast<std::size_t>(bucket(static_cast<std::uint64_t>(ns)))];
}

std::int64_t LatenessHistogram::quantile(double q) const {
  if (count_ == 0) return 0;
  const auto rank =
      static_cast<std::uint64_t>(std::ceil(std::clamp(q, 0.0, 1.0) * static_cast<double>(count_)));
  std::uint64_t acc = 0;
  for (int b = 0; b < kBuckets; ++b) {
    acc += n_[static_cast<std::size_t>(b)];
    if (acc >= std::max<std::uint64_t>(rank, 1)) return std::clamp(upper(b), min_, max_);
  }
  return max_;
}

}  // namespace fs::fw
