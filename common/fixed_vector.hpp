#pragma once
// FixedVector<T, N>: a vector with inline storage for at most N elements; never allocates.
// push_back/emplace_back/insert beyond N throw fs::Error ("FixedVector capacity N exceeded");
// try_push_back returns false instead (for hot paths that flag overflow rather than throw).
#include <algorithm>
#include <cstddef>
#include <initializer_list>
#include <iterator>
#include <memory>
#include <new>
#include <span>
#include <string>
#include <type_traits>
#include <utility>

#include "common/error.hpp"

namespace fs {

template <class T, std::size_t N>
class FixedVector {
 public:
  using value_type = T;
  using size_type = std::size_t;
  using reference = T&;
  using const_reference = const T&;
  using iterator = T*;
  using const_iterator = const T*;

  FixedVector() = default;
  FixedVector(std::initializer_list<T> init) {
    for (const T& v : init) push_back(v);
  }
  explicit FixedVector(size_type n, const T& v = T()) { assign(n, v); }
  FixedVector(const FixedVector& o) {
    for (const T& v : o) unchecked_emplace(v);
  }
  FixedVector(FixedVector&& o) noexcept(std::is_nothrow_move_constructible_v<T>) {
    for (T& v : o) unchecked_emplace(std::move(v));
    o.clear();
  }
  FixedVector& operator=(const FixedVector& o) {
    if (this != &o) {
      clear();
      for (const T& v : o) unchecked_emplace(v);
    }
    return *this;
  }
  FixedVector& operator=(FixedVector&& o) noexcept(std::is_nothrow_move_constructible_v<T>) {
    if (this != &o) {
      clear();
      for (T& v : o) unchecked_emplace(std::move(v));
      o.clear();
    }
    return *this;
  }
  ~FixedVector() { clear(); }

  static constexpr size_type capacity() { return N; }
  static constexpr size_type max_size() { return N; }
  size_type size() const { return size_; }
  bool empty() const { return size_ == 0; }
  bool full() const { return size_ == N; }

  T* data() { return std::launder(reinterpret_cast<T*>(storage_)); }
  const T* data() const { return std::launder(reinterpret_cast<const T*>(storage_)); }
  iterator begin() { return data(); }
  iterator end() { return data() + size_; }
  const_iterator begin() const { return data(); }
  const_iterator end() const { return data() + size_; }
  const_iterator cbegin() const { return begin(); }
  const_iterator cend() const { return end(); }

  T& operator[](size_type i) { return data()[i]; }
  const T& operator[](size_type i) const { return data()[i]; }
  T& at(size_type i) {
    check_index(i);
    return data()[i];
  }
  const T& at(size_type i) const {
    check_index(i);
    return data()[i];
  }
  T& front() { return data()[0]; }
  const T& front() const { return data()[0]; }
  T& back() { return data()[size_ - 1]; }
  const T& back() const { return data()[size_ - 1]; }

  operator std::span<T>() { return {data(), size_}; }
  operator std::span<const T>() const { return {data(), size_}; }
  std::span<T> span() { return {data(), size_}; }
  std::span<const T> span() const { return {data(), size_}; }

  void push_back(const T& v) { emplace_back(v); }
  void push_back(T&& v) { emplace_back(std::move(v)); }
  template <class... Args>
  T& emplace_back(Args&&... args) {
    if (size_ == N) overflow();
    return unchecked_emplace(std::forward<Args>(args)...);
  }
  bool try_push_back(const T& v) {
    if (size_ == N) return false;
    unchecked_emplace(v);
    return true;
  }
  bool try_push_back(T&& v) {
    if (size_ == N) return false;
    unchecked_emplace(std::move(v));
    return true;
  }
  void pop_back() {
    std::destroy_at(data() + size_ - 1);
    --size_;
  }
  void clear() {
    std::destroy(begin(), end());
    size_ = 0;
  }
  void resize(size_type n) {
    if (n > N) overflow();
    while (size_ > n) pop_back();
    while (size_ < n) unchecked_emplace();
  }
  void resize(size_type n, const T& v) {
    if (n > N) overflow();
    while (size_ > n) pop_back();
    while (size_ < n) unchecked_emplace(v);
  }
  void assign(size_type n, const T& v) {
    clear();
    resize(n, v);
  }
  iterator insert(const_iterator pos, const T& v) {
    if (size_ == N) overflow();
    const size_type i = static_cast<size_type>(pos - begin());
    unchecked_emplace(v);
    std::rotate(begin() + i, end() - 1, end());
    return begin() + i;
  }
  iterator erase(const_iterator pos) {
    const size_type i = static_cast<size_type>(pos - begin());
    std::move(begin() + i + 1, end(), begin() + i);
    pop_back();
    return begin() + i;
  }

  friend bool operator==(const FixedVector& a, const FixedVector& b) {
    return std::equal(a.begin(), a.end(), b.begin(), b.end());
  }

 private:
  template <class... Args>
  T& unchecked_emplace(Args&&... args) {
    T* p = ::new (static_cast<void*>(data() + size_)) T(std::forward<Args>(args)...);
    ++size_;
    return *p;
  }
  [[noreturn]] static void overflow() {
    throw Error("FixedVector capacity " + std::to_string(N) + " exceeded");
  }
  void check_index(size_type i) const {
    if (i >= size_)
      throw Error("FixedVector index " + std::to_string(i) + " out of range (size " + std::to_string(size_) +
                  ")");
  }

  alignas(T) std::byte storage_[sizeof(T) * (N == 0 ? 1 : N)];
  size_type size_ = 0;
};

}  // namespace fs
