#include "common/byte_buffer.hpp"

#include <sys/mman.h>

#include <algorithm>
#include <cstring>
#include <new>
#include <utility>

namespace fs {

namespace {

constexpr std::size_t kHugePage = ByteBuffer::kHugeBufferBytes;

// A mapping of at least n bytes (a multiple of the huge page size), advised for huge pages; nullptr when
// the system refuses it.
std::byte* map_bytes(std::size_t n) {
  void* p = ::mmap(nullptr, n, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) return nullptr;
#ifdef MADV_HUGEPAGE
  // Advice only: a kernel without transparent huge pages leaves the mapping in small pages.
  ::madvise(p, n, MADV_HUGEPAGE);
#endif
  return static_cast<std::byte*>(p);
}

}  // namespace

ByteBuffer::ByteBuffer(ByteBuffer&& other) noexcept
    : data_(std::exchange(other.data_, nullptr)),
      size_(std::exchange(other.size_, 0)),
      capacity_(std::exchange(other.capacity_, 0)),
      mapped_(std::exchange(other.mapped_, false)) {}

ByteBuffer& ByteBuffer::operator=(ByteBuffer&& other) noexcept {
  if (this != &other) {
    release();
    data_ = std::exchange(other.data_, nullptr);
    size_ = std::exchange(other.size_, 0);
    capacity_ = std::exchange(other.capacity_, 0);
    mapped_ = std::exchange(other.mapped_, false);
  }
  return *this;
}

ByteBuffer::~ByteBuffer() { release(); }

void ByteBuffer::release() noexcept {
  if (data_ == nullptr) return;
  if (mapped_)
    ::munmap(data_, capacity_);
  else
    delete[] data_;
  data_ = nullptr;
  size_ = capacity_ = 0;
  mapped_ = false;
}

void ByteBuffer::resize(std::size_t n) {
  if (n <= capacity_) {
    size_ = n;
    return;
  }
  std::size_t want = std::max(n, capacity_ + capacity_ / 2);
  std::byte* fresh = nullptr;
  bool mapped = false;
  if (want >= kHugeBufferBytes) {
    if (want > static_cast<std::size_t>(-1) - kHugePage) throw std::bad_alloc();
    want = (want + kHugePage - 1) / kHugePage * kHugePage;
    fresh = map_bytes(want);
    mapped = fresh != nullptr;
  }
  if (fresh == nullptr) fresh = new std::byte[want];  // uninitialised (default-initialised bytes)
  if (size_ > 0) std::memcpy(fresh, data_, size_);
  release();
  data_ = fresh;
  capacity_ = want;
  mapped_ = mapped;
  size_ = n;
}

}  // namespace fs
