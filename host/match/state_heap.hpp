#pragma once
// Internal to the inexact matcher: the priority queue of open search states (thesis ch. 7.2.4, best-first),
// a binary heap of entries that carry their ordering key (no state pool access while sifting). Capacity is
// reserved for every pool entry up front: push never reallocates.
#include <cstddef>
#include <vector>

namespace fs::host::match::detail {

// Priority queue entry: the ordering key is copied out of the state.
struct HeapItem {
  double cost;
  int level;
  int id;
};
// Lowest cost first; among equal costs the deeper state (favours well developed paths, 7.2.4), then the older
// one.
inline bool heap_less(const HeapItem& x, const HeapItem& y) {
  if (x.cost != y.cost) return x.cost < y.cost;
  if (x.level != y.level) return x.level > y.level;
  return x.id < y.id;
}

class StateHeap {
 public:
  void reserve(std::size_t n) { heap_.reserve(n); }
  void clear() { heap_.clear(); }
  bool empty() const { return heap_.empty(); }
  const HeapItem& front() const { return heap_.front(); }

  void push(const HeapItem& entry) {
    heap_.push_back(entry);  // capacity reserved for every pool entry: never reallocates
    std::size_t i = heap_.size() - 1;
    const HeapItem item = heap_[i];
    while (i > 0) {
      const std::size_t p = (i - 1) / 2;
      if (!heap_less(item, heap_[p])) break;
      heap_[i] = heap_[p];
      i = p;
    }
    heap_[i] = item;
  }
  // Removes the lowest entry and returns its state id.
  int pop() {
    const int top = heap_.front().id;
    const HeapItem item = heap_.back();
    heap_.pop_back();
    const std::size_t n = heap_.size();
    if (n == 0) return top;
    std::size_t i = 0;
    for (;;) {
      const std::size_t l = 2 * i + 1, r = l + 1;
      if (l >= n) break;
      std::size_t m = l;
      if (r < n && heap_less(heap_[r], heap_[l])) m = r;
      if (!heap_less(heap_[m], item)) break;
      heap_[i] = heap_[m];
      i = m;
    }
    heap_[i] = item;
    return top;
  }

 private:
  std::vector<HeapItem> heap_;
};

}  // namespace fs::host::match::detail
