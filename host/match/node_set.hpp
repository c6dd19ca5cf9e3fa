#pragma once
// Fixed-size node bitset (graphs of up to kMaxNodes nodes) for the matchers' core / terminal / rest sets.
#include <array>
#include <bit>
#include <cstdint>

namespace fs::host::match {

inline constexpr int kMaxNodes = 128;

struct NodeSet {
  static constexpr int kWords = kMaxNodes / 64;
  std::array<std::uint64_t, kWords> w{};

  void set(int i) { w[static_cast<unsigned>(i) >> 6] |= std::uint64_t{1} << (i & 63); }
  void reset(int i) { w[static_cast<unsigned>(i) >> 6] &= ~(std::uint64_t{1} << (i & 63)); }
  bool test(int i) const { return (w[static_cast<unsigned>(i) >> 6] >> (i & 63)) & 1U; }
  bool any() const {
    for (auto x : w)
      if (x) return true;
    return false;
  }
  int count() const {
    int c = 0;
    for (auto x : w) c += std::popcount(x);
    return c;
  }
  NodeSet operator&(const NodeSet& o) const {
    NodeSet r;
    for (int i = 0; i < kWords; ++i) r.w[i] = w[i] & o.w[i];
    return r;
  }
  NodeSet operator|(const NodeSet& o) const {
    NodeSet r;
    for (int i = 0; i < kWords; ++i) r.w[i] = w[i] | o.w[i];
    return r;
  }
  NodeSet operator~() const {
    NodeSet r;
    for (int i = 0; i < kWords; ++i) r.w[i] = ~w[i];
    return r;
  }
  NodeSet minus(const NodeSet& o) const {
    NodeSet r;
    for (int i = 0; i < kWords; ++i) r.w[i] = w[i] & ~o.w[i];
    return r;
  }
  bool subset_of(const NodeSet& o) const {
    for (int i = 0; i < kWords; ++i)
      if (w[i] & ~o.w[i]) return false;
    return true;
  }
  bool operator==(const NodeSet& o) const {  // word by word (the defaulted one may call memcmp)
    std::uint64_t d = 0;
    for (int i = 0; i < kWords; ++i) d |= w[i] ^ o.w[i];
    return d == 0;
  }

  // Calls f(index) for every member in ascending order.
  template <class F>
  void for_each(F&& f) const {
    for (int k = 0; k < kWords; ++k) {
      std::uint64_t x = w[k];
      while (x) {
        const int b = std::countr_zero(x);
        f(k * 64 + b);
        x &= x - 1;
      }
    }
  }
};

}  // namespace fs::host::match
