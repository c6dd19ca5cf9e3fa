#pragma once
// A growable buffer of uninitialised bytes for whole files read into memory (libraries, point clouds).
// Growing never zero-fills: read() overwrites the bytes anyway. From kHugeBufferBytes on, the bytes come from
// their own anonymous mapping advised for transparent huge pages (MADV_HUGEPAGE), so a 30 MB file costs a
// few dozen page faults instead of thousands: where a page fault is expensive (virtual machines), faulting a
// large read buffer page by page cost more than parsing it. Smaller buffers come from operator new.
#include <cstddef>
#include <span>

namespace fs {

class ByteBuffer {
 public:
  static constexpr std::size_t kHugeBufferBytes = std::size_t{2} << 20;

  ByteBuffer() = default;
  explicit ByteBuffer(std::size_t size) { resize(size); }
  ByteBuffer(ByteBuffer&& other) noexcept;
  ByteBuffer& operator=(ByteBuffer&& other) noexcept;
  ByteBuffer(const ByteBuffer&) = delete;
  ByteBuffer& operator=(const ByteBuffer&) = delete;
  ~ByteBuffer();

  std::byte* data() { return data_; }
  const std::byte* data() const { return data_; }
  std::byte& operator[](std::size_t i) { return data_[i]; }
  const std::byte& operator[](std::size_t i) const { return data_[i]; }
  std::size_t size() const { return size_; }
  std::size_t capacity() const { return capacity_; }
  bool empty() const { return size_ == 0; }
  // Whether the bytes are in a mapping of their own (advised for huge pages) rather than from operator new.
  bool mapped() const { return mapped_; }
  std::span<const std::byte> span() const { return {data_, size_}; }
  std::span<std::byte> span() { return {data_, size_}; }

  // New bytes are uninitialised; the first min(size, n) keep their values. Growth beyond the capacity
  // allocates 1.5x (at least n) and copies. Throws std::bad_alloc when memory cannot be had.
  void resize(std::size_t n);

 private:
  void release() noexcept;

  std::byte* data_ = nullptr;
  std::size_t size_ = 0;
  std::size_t capacity_ = 0;
  bool mapped_ = false;
};

}  // namespace fs
