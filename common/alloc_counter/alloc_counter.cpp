#include "common/alloc_counter/alloc_counter.hpp"

#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <new>

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define FS_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define FS_ASAN 1
#endif

#if defined(FS_ASAN)
// From <sanitizer/allocator_interface.h> (not shipped with every compiler's headers).
extern "C" int __sanitizer_install_malloc_and_free_hooks(void (*malloc_hook)(const volatile void*,
                                                                             std::size_t),
                                                         void (*free_hook)(const volatile void*));
#elif defined(__GLIBC__)
#define FS_INTERPOSE_MALLOC 1
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void __libc_free(void*);
}
#endif

namespace {

// Plain thread-local PODs: static TLS in the executable, no allocation on first use.
thread_local std::uint64_t t_allocs = 0, t_frees = 0, t_bytes = 0, t_news = 0;
std::atomic<std::uint64_t> g_allocs{0}, g_frees{0}, g_bytes{0}, g_news{0};

inline void count_alloc(std::size_t n) {
  ++t_allocs;
  t_bytes += n;
  g_allocs.fetch_add(1, std::memory_order_relaxed);
  g_bytes.fetch_add(n, std::memory_order_relaxed);
}
inline void count_free() {
  ++t_frees;
  g_frees.fetch_add(1, std::memory_order_relaxed);
}
inline void count_new() {
  ++t_news;
  g_news.fetch_add(1, std::memory_order_relaxed);
}

#if defined(FS_ASAN)
void on_malloc(const volatile void* p, std::size_t n) {
  if (p) count_alloc(n);
}
void on_free(const volatile void* p) {
  if (p) count_free();
}
struct InstallHooks {
  InstallHooks() { __sanitizer_install_malloc_and_free_hooks(on_malloc, on_free); }
} install_hooks;
#endif

#if defined(FS_INTERPOSE_MALLOC)
inline void* raw_malloc(std::size_t n) { return __libc_malloc(n); }
inline void raw_free(void* p) { __libc_free(p); }
inline void* raw_aligned(std::size_t align, std::size_t n) { return __libc_memalign(align, n); }
#else
inline void* raw_malloc(std::size_t n) { return std::malloc(n); }
inline void raw_free(void* p) { std::free(p); }
inline void* raw_aligned(std::size_t align, std::size_t n) {
  // aligned_alloc needs n to be a multiple of align.
  return std::aligned_alloc(align, (n + align - 1) / align * align);
}
#endif

// Under ASan the hook counts the underlying malloc; otherwise our malloc wrapper does (interposed) or we
// count here (no interposition).
inline void* new_impl(std::size_t n) {
  count_new();
  if (n == 0) n = 1;
#if defined(FS_INTERPOSE_MALLOC)
  void* p = raw_malloc(n);
  if (p) count_alloc(n);
#elif defined(FS_ASAN)
  void* p = raw_malloc(n);
#else
  void* p = raw_malloc(n);
  if (p) count_alloc(n);
#endif
  return p;
}
inline void* new_aligned_impl(std::size_t n, std::size_t align) {
  count_new();
  if (n == 0) n = 1;
  void* p = raw_aligned(align, n);
#if !defined(FS_ASAN)
  if (p) count_alloc(n);
#endif
  return p;
}
inline void delete_impl(void* p) {
  if (!p) return;
#if !defined(FS_ASAN)
  count_free();
#endif
  raw_free(p);
}

}  // namespace

// ---- malloc family (glibc, non-ASan)
// -------------------------------------------------------------------------

#if defined(FS_INTERPOSE_MALLOC)
extern "C" {
void* malloc(std::size_t n) {
  void* p = __libc_malloc(n);
  if (p) count_alloc(n);
  return p;
}
void* calloc(std::size_t a, std::size_t b) {
  void* p = __libc_calloc(a, b);
  if (p) count_alloc(a * b);
  return p;
}
void* realloc(void* old, std::size_t n) {
  void* p = __libc_realloc(old, n);
  if (p && p != old) {
    count_alloc(n);
    if (old) count_free();
  } else if (!old && p) {
    count_alloc(n);
  } else if (old && !p && n == 0) {
    count_free();  // realloc(p, 0) frees p
  }
  return p;
}
void free(void* p) {
  if (p) count_free();
  __libc_free(p);
}
void* memalign(std::size_t align, std::size_t n) {
  void* p = __libc_memalign(align, n);
  if (p) count_alloc(n);
  return p;
}
void* aligned_alloc(std::size_t align, std::size_t n) {
  void* p = __libc_memalign(align, n);
  if (p) count_alloc(n);
  return p;
}
int posix_memalign(void** out, std::size_t align, std::size_t n) {
  if (align < sizeof(void*) || (align & (align - 1)) != 0) return EINVAL;
  void* p = __libc_memalign(align, n);
  if (!p) return ENOMEM;
  count_alloc(n);
  *out = p;
  return 0;
}
}
#endif

// ---- operator new / delete
// -----------------------------------------------------------------------------------

void* operator new(std::size_t n) {
  void* p = new_impl(n);
  if (!p) throw std::bad_alloc();
  return p;
}
void* operator new[](std::size_t n) {
  void* p = new_impl(n);
  if (!p) throw std::bad_alloc();
  return p;
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return new_impl(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return new_impl(n); }
void* operator new(std::size_t n, std::align_val_t a) {
  void* p = new_aligned_impl(n, static_cast<std::size_t>(a));
  if (!p) throw std::bad_alloc();
  return p;
}
void* operator new[](std::size_t n, std::align_val_t a) {
  void* p = new_aligned_impl(n, static_cast<std::size_t>(a));
  if (!p) throw std::bad_alloc();
  return p;
}
void* operator new(std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
  return new_aligned_impl(n, static_cast<std::size_t>(a));
}
void* operator new[](std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
  return new_aligned_impl(n, static_cast<std::size_t>(a));
}
void operator delete(void* p) noexcept { delete_impl(p); }
void operator delete[](void* p) noexcept { delete_impl(p); }
void operator delete(void* p, std::size_t) noexcept { delete_impl(p); }
void operator delete[](void* p, std::size_t) noexcept { delete_impl(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { delete_impl(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { delete_impl(p); }
void operator delete(void* p, std::align_val_t) noexcept { delete_impl(p); }
void operator delete[](void* p, std::align_val_t) noexcept { delete_impl(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { delete_impl(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { delete_impl(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { delete_impl(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { delete_impl(p); }

// ---- AllocCounter
// ----------------------------------------------------------------------------------------------

namespace fs {

AllocStats AllocCounter::thread_totals() { return AllocStats{t_allocs, t_frees, t_bytes, t_news}; }
AllocStats AllocCounter::process_totals() {
  return AllocStats{g_allocs.load(std::memory_order_relaxed), g_frees.load(std::memory_order_relaxed),
                    g_bytes.load(std::memory_order_relaxed), g_news.load(std::memory_order_relaxed)};
}
bool AllocCounter::counts_malloc() {
#if defined(FS_ASAN) || defined(FS_INTERPOSE_MALLOC)
  return true;
#else
  return false;
#endif
}

AllocCounter::AllocCounter() { restart(); }
void AllocCounter::restart() {
  thread0_ = thread_totals();
  process0_ = process_totals();
}
std::uint64_t AllocCounter::allocations() const { return t_allocs - thread0_.allocations; }
std::uint64_t AllocCounter::deallocations() const { return t_frees - thread0_.deallocations; }
std::uint64_t AllocCounter::bytes() const { return t_bytes - thread0_.bytes; }
std::uint64_t AllocCounter::new_calls() const { return t_news - thread0_.new_calls; }
std::uint64_t AllocCounter::process_allocations() const {
  return g_allocs.load(std::memory_order_relaxed) - process0_.allocations;
}
AllocStats AllocCounter::thread_stats() const {
  return AllocStats{allocations(), deallocations(), bytes(), new_calls()};
}

}  // namespace fs
