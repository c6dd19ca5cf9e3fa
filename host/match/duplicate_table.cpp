#include "host/match/duplicate_table.hpp"

namespace fs::host::match::detail {

DuplicateTable::DuplicateTable(std::size_t states) {
  std::size_t t = 16;
  while (t < 2 * states) t <<= 1;
  table_.resize(t);
  mask_ = t - 1;
}

void DuplicateTable::next_gen() {
  if (++gen_ == 0) {  // wrapped: clear the table once every 2^32 generations
    for (auto& sl : table_) sl = Slot{};
    gen_ = 1;
  }
}

void DuplicateTable::reset() {
  std::fill(bloom_.begin(), bloom_.end(), 0);
  next_gen();
  mask_ = std::min<std::uint64_t>(kInitialSlots, table_.size()) - 1;
}

void DuplicateTable::place(std::uint64_t h, int state) {
  std::uint64_t i = h & mask_;
  while (table_[i].gen == gen_) i = (i + 1) & mask_;
  table_[i] = Slot{h, gen_, state};
}

void DuplicateTable::insert(std::uint64_t h, int state, std::span<const State> pool) {
  // state - 1 states are in the table (every created state, root excluded).
  if (2 * static_cast<std::uint64_t>(state) > mask_ + 1 && mask_ + 1 < table_.size()) {
    mask_ = 2 * mask_ + 1;
    next_gen();
    for (int k = 1; k < state; ++k) place(pool[static_cast<std::size_t>(k)].hash, k);
  }
  place(h, state);
  bloom_set(h);
}

}  // namespace fs::host::match::detail
