#pragma once
// SpscRing<T>: a lock-free single-producer / single-consumer ring of T slots, allocated once at construction
// (capacity rounded up to a power of two). Slots are reused, so T may own buffers (e.g. a frame buffer
// vector reserved at start-up with prepare_slots()) and nothing allocates afterwards when they are filled
// in place:
//
//   producer:  if (Frame* slot = ring.acquire()) { fill(*slot); ring.publish(); } else { /* full: drop */ }
//   consumer:  if (Frame* f = ring.front()) { use(*f); ring.pop(); }
//
// or by value with try_push / try_pop. Exactly one producer thread and one consumer thread.
#include <atomic>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <utility>

#include "common/error.hpp"

namespace fs {

template <class T>
class SpscRing {
 public:
  // `init` is copied into every slot (e.g. a vector with reserved capacity).
  explicit SpscRing(std::size_t capacity, const T& init = T()) {
    if (capacity == 0 || capacity > (std::size_t{1} << 30))
      throw Error("SpscRing capacity " + std::to_string(capacity) + " out of range 1..2^30");
    cap_ = std::bit_ceil(capacity);
    mask_ = cap_ - 1;
    slots_ = std::make_unique<T[]>(cap_);
    for (std::size_t i = 0; i < cap_; ++i) slots_[i] = init;
  }
  SpscRing(const SpscRing&) = delete;
  SpscRing& operator=(const SpscRing&) = delete;

  std::size_t capacity() const { return cap_; }

  // Set-up before the threads start: f(slot) for every slot (e.g. reserve a buffer's capacity; copying a
  // vector does not copy its capacity).
  template <class F>
  void prepare_slots(F&& f) {
    for (std::size_t i = 0; i < cap_; ++i) f(slots_[i]);
  }

  // ---- producer side ----
  // The next free slot, or nullptr when full. Fill it, then publish().
  T* acquire() {
    const std::size_t h = head_.load(std::memory_order_relaxed);
    if (h - tail_cache_ == cap_) {
      tail_cache_ = tail_.load(std::memory_order_acquire);
      if (h - tail_cache_ == cap_) return nullptr;
    }
    return &slots_[h & mask_];
  }
  void publish() { head_.store(head_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }
  bool try_push(const T& v) {
    T* s = acquire();
    if (!s) return false;
    *s = v;
    publish();
    return true;
  }
  bool try_push(T&& v) {
    T* s = acquire();
    if (!s) return false;
    *s = std::move(v);
    publish();
    return true;
  }

  // ---- consumer side ----
  // The oldest published slot, or nullptr when empty. Use it, then pop().
  T* front() {
    const std::size_t t = tail_.load(std::memory_order_relaxed);
    if (t == head_cache_) {
      head_cache_ = head_.load(std::memory_order_acquire);
      if (t == head_cache_) return nullptr;
    }
    return &slots_[t & mask_];
  }
  void pop() { tail_.store(tail_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }
  // Moves the element out (a buffer-owning slot loses its buffer: prefer front()/pop() for those).
  bool try_pop(T& out) {
    T* s = front();
    if (!s) return false;
    out = std::move(*s);
    pop();
    return true;
  }

  // Approximate (exact when called from either side while the other is idle).
  std::size_t size() const {
    return head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire);
  }
  bool empty() const { return size() == 0; }

 private:
  static constexpr std::size_t kLine = 64;
  std::size_t cap_ = 0, mask_ = 0;
  std::unique_ptr<T[]> slots_;
  alignas(kLine) std::atomic<std::size_t> head_{0};  // written by the producer
  std::size_t tail_cache_ = 0;                       // producer's copy of tail_
  alignas(kLine) std::atomic<std::size_t> tail_{0};  // written by the consumer
  std::size_t head_cache_ = 0;                       // consumer's copy of head_
};

}  // namespace fs
