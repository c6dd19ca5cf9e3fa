#pragma once
// Fixed-memory histogram of wake-up lateness (ns): log-linear buckets (16 per power of two, <= 6 % relative
// error), exact min / max / count. Quantiles return the upper edge of the bucket holding the quantile.
#include <array>
#include <cstdint>

namespace fs::fw {

class LatenessHistogram {
 public:
  void add(std::int64_t ns);
  void clear() { *this = LatenessHistogram{}; }
  std::uint64_t count() const { return count_; }
  std::int64_t min() const { return count_ ? min_ : 0; }
  std::int64_t max() const { return count_ ? max_ : 0; }
  std::int64_t quantile(double q) const;  // q in [0, 1]

 private:
  static constexpr int kSub = 16;
  static constexpr int kBuckets = 64 * kSub;
  static int bucket(std::uint64_t v);
  static std::int64_t upper(int b);
  std::array<std::uint64_t, kBuckets> n_{};
  std::uint64_t count_ = 0;
  std::int64_t min_ = 0, max_ = 0;
};

}  // namespace fs::fw
