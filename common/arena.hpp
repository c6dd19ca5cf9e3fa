#pragma once
// A fixed-size arena: std::pmr::monotonic_buffer_resource over one buffer allocated up front, with
// std::pmr::null_memory_resource() upstream, so running out throws fs::ArenaExhausted instead of silently
// falling back to the heap. Use it as the memory_resource of std::pmr containers, or directly:
//
//   fs::Arena arena(1 << 20, "segmentation");          // the only heap allocation
//   std::pmr::vector<int> v(&arena); v.reserve(1000);  // from the arena
//   auto pts = arena.allocate_array<Vec3>(4096);       // std::span<Vec3>, default-constructed
//   arena.reset();                                     // everything released at once (per scan)
//
// Deallocation is a no-op (monotonic); memory comes back with reset(). Not thread-safe.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <memory_resource>
#include <new>
#include <span>
#include <string>
#include <type_traits>
#include <utility>

#include "common/error.hpp"

namespace fs {

class ArenaExhausted : public Error {
 public:
  using Error::Error;
};

class Arena final : public std::pmr::memory_resource {
 public:
  // Allocates `capacity` bytes once (operator new).
  explicit Arena(std::size_t capacity, std::string name = "arena")
      : owned_(new std::byte[capacity == 0 ? 1 : capacity]),
        begin_(owned_.get()),
        capacity_(capacity),
        name_(std::move(name)),
        mono_(begin_, capacity_ == 0 ? 1 : capacity_, std::pmr::null_memory_resource()) {}
  // Over caller-provided memory (not owned); no heap allocation at all.
  explicit Arena(std::span<std::byte> buffer, std::string name = "arena")
      : begin_(buffer.data()),
        capacity_(buffer.size()),
        name_(std::move(name)),
        mono_(buffer.data(), buffer.size(), std::pmr::null_memory_resource()) {}
  Arena(const Arena&) = delete;
  Arena& operator=(const Arena&) = delete;

  std::size_t capacity() const { return capacity_; }
  // Bytes consumed since the last reset (including alignment padding).
  std::size_t used() const { return used_; }
  std::size_t remaining() const { return capacity_ - used_; }
  // Largest used() ever seen (to size budgets).
  std::size_t high_water() const { return high_water_; }
  const std::string& name() const { return name_; }

  // Releases everything allocated so far; the whole buffer is available again.
  void reset() {
    mono_.release();
    used_ = 0;
  }

  // n value-initialised objects of T (trivially destructible only: reset() runs no
  // destructors).
  template <class T>
  std::span<T> allocate_array(std::size_t n) {
    static_assert(std::is_trivially_destructible_v<T>, "the arena runs no destructors");
    if (n > max_count<T>()) throw exhausted(static_cast<std::size_t>(-1), alignof(T));
    T* p = static_cast<T*>(allocate(n * sizeof(T), alignof(T)));
    for (std::size_t i = 0; i < n; ++i) ::new (static_cast<void*>(p + i)) T();
    return {p, n};
  }
  // Like allocate_array but returns an empty span instead of throwing when the arena cannot hold n objects
  // (for budgets that end a search cleanly with a flag).
  template <class T>
  std::span<T> try_allocate_array(std::size_t n) {
    static_assert(std::is_trivially_destructible_v<T>, "the arena runs no destructors");
    if (n == 0 || n > max_count<T>() || !fits(n * sizeof(T), alignof(T))) return {};
    return allocate_array<T>(n);
  }
  // Whether allocate(bytes, align) would succeed now.
  bool fits(std::size_t bytes, std::size_t align) const {
    const auto base = reinterpret_cast<std::uintptr_t>(begin_);
    const std::uintptr_t next = (base + used_ + align - 1) / align * align;
    return next - base <= capacity_ && capacity_ - (next - base) >= (bytes == 0 ? 1 : bytes);
  }

  template <class T, class... Args>
  T* make(Args&&... args) {
    static_assert(std::is_trivially_destructible_v<T>, "the arena runs no destructors");
    return ::new (allocate(sizeof(T), alignof(T))) T(std::forward<Args>(args)...);
  }

 private:
  template <class T>
  static constexpr std::size_t max_count() {
    return static_cast<std::size_t>(-1) / sizeof(T);
  }
  ArenaExhausted exhausted(std::size_t bytes, std::size_t align) const {
    return ArenaExhausted(
        "arena '" + name_ + "' exhausted: request of " +
        (bytes == static_cast<std::size_t>(-1) ? std::string("(overflowing size)") : std::to_string(bytes)) +
        " bytes (alignment " + std::to_string(align) + ") with " + std::to_string(used_) + " of " +
        std::to_string(capacity_) + " bytes used");
  }
  void* do_allocate(std::size_t bytes, std::size_t align) override {
    void* p;
    try {
      p = mono_.allocate(bytes == 0 ? 1 : bytes, align);
    } catch (const std::bad_alloc&) {
      throw exhausted(bytes, align);
    }
    const std::size_t end = static_cast<std::size_t>(static_cast<std::byte*>(p) - begin_) + bytes;
    if (end > used_) used_ = end;
    if (used_ > high_water_) high_water_ = used_;
    return p;
  }
  void do_deallocate(void*, std::size_t, std::size_t) override {}
  bool do_is_equal(const std::pmr::memory_resource& other) const noexcept override { return this == &other; }

  std::unique_ptr<std::byte[]> owned_;
  std::byte* begin_;
  std::size_t capacity_;
  std::string name_;
  std::size_t used_ = 0, high_water_ = 0;
  std::pmr::monotonic_buffer_resource mono_;
};

}  // namespace fs
