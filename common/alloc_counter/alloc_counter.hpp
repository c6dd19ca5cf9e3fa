#pragma once
// Counts heap allocations, for tests that prove a hot path allocates nothing after warm-up.
//
// Link the target fs_alloc_counter into a test executable. It replaces the global operator new/delete
// (every form) and counts malloc-family calls:
//  * normal builds (glibc): malloc/calloc/realloc/aligned_alloc/posix_memalign/memalign are interposed and
//    forwarded to glibc's __libc_* functions;
//  * AddressSanitizer builds: ASan owns malloc, so the counter registers the sanitizer's malloc hook
//    (__sanitizer_install_malloc_and_free_hooks), which sees every allocation ASan serves.
// Counting is per thread (the scope counts what its own thread allocates) and process-wide.
//
//   fs::AllocCounter c;            // starts counting
//   hot_path();
//   EXPECT_EQ(c.allocations(), 0u);
#include <cstdint>

namespace fs {

struct AllocStats {
  std::uint64_t allocations = 0;  // malloc-family + operator new calls that returned memory
  std::uint64_t deallocations = 0;
  std::uint64_t bytes = 0;      // bytes requested by those allocations
  std::uint64_t new_calls = 0;  // of which operator new / new[]
};

class AllocCounter {
 public:
  AllocCounter();  // snapshot of the counters
  // Allocations on this thread since construction (or restart()).
  std::uint64_t allocations() const;
  std::uint64_t deallocations() const;
  std::uint64_t bytes() const;
  std::uint64_t new_calls() const;
  // All threads of the process since construction.
  std::uint64_t process_allocations() const;
  AllocStats thread_stats() const;
  void restart();

  // True when malloc calls made outside operator new are counted too (see the header comment); false
  // where only operator new is counted.
  static bool counts_malloc();
  // Totals since process start.
  static AllocStats thread_totals();
  static AllocStats process_totals();

 private:
  AllocStats thread0_, process0_;
};

}  // namespace fs
