#pragma once
// Internal to the inexact matcher: the duplicate test of the new match condition (thesis table 7.6, condition
// 5), a hash set of the created states keyed by their match-set hash (detail::pair_key, Zobrist). Open
// addressing in slots reserved up front; a one-hash Bloom filter answers most misses without a table probe.
// Fixed memory: no allocation after construction.
#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>

#include "host/match/search_state.hpp"

namespace fs::host::match::detail {

class DuplicateTable {
 public:
  // Room for the states of a pool of `states` entries (the table holds up to half its slots).
  explicit DuplicateTable(std::size_t states);

  // Empties the table for a new match (a new generation) at its initial size.
  void reset();
  // Fetches the slot of hash h into the cache (probed by contains(), written by insert()).
  void prefetch(std::uint64_t h) const { __builtin_prefetch(&table_[h & mask_]); }
  // True when a state with hash h is stored for which same(state id) holds.
  template <class Same>
  bool contains(std::uint64_t h, Same same) const {
    if (!bloom_test(h)) return false;  // most candidates: no table probe
    for (std::uint64_t i = h & mask_;; i = (i + 1) & mask_) {
      const Slot& sl = table_[i];
      if (sl.gen != gen_) return false;
      if (sl.hash != h) continue;
      if (same(sl.state)) return true;
    }
  }
  // Stores state number `state` (>= 1) with hash h; pool[1 .. state) are the states stored so far
  // (re-inserted when the table grows).
  void insert(std::uint64_t h, int state, std::span<const State> pool);

 private:
  struct Slot {
    std::uint64_t hash = 0;
    std::uint32_t gen = 0;
    int state = -1;
  };
  // The table starts small (cache-resident for the usual few thousand states) and doubles inside the slots
  // reserved up front when it becomes half full: a new generation, and the created states re-inserted.
  static constexpr std::uint64_t kInitialSlots = 4096;
  // A one-hash Bloom filter of the table's hashes (16 KB, stays in L1/L2): a clear bit proves absence.
  static constexpr std::uint64_t kBloomBits = std::uint64_t{1} << 17;
  static std::uint64_t bloom_bit(std::uint64_t h) { return (h >> 40) & (kBloomBits - 1); }
  bool bloom_test(std::uint64_t h) const { return (bloom_[bloom_bit(h) >> 6] >> (bloom_bit(h) & 63)) & 1U; }
  void bloom_set(std::uint64_t h) { bloom_[bloom_bit(h) >> 6] |= std::uint64_t{1} << (bloom_bit(h) & 63); }
  void next_gen();
  void place(std::uint64_t h, int state);

  std::vector<Slot> table_;
  std::uint64_t mask_ = 0;
  std::uint32_t gen_ = 0;
  std::vector<std::uint64_t> bloom_ = std::vector<std::uint64_t>(kBloomBits / 64);
};

}  // namespace fs::host::match::detail
