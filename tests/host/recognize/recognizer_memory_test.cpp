// The memory budget's model of the recognizer (ScanLimits, host/io/scan.hpp;
// docs/host-pipeline.md#memory-budget) against the heap bytes that constructing one requests, per grid cell:
// the slope between two grid sizes (the fixed part, the library's tables and the workers', cancels). It must
// stay at or above what the code requests, or a scan admitted under --memory-budget could need more than the
// budget, and within 15 % of it, so that the model follows the code.
#include <gtest/gtest.h>

#include <cstddef>
#include <cstdint>

#include "common/alloc_counter/alloc_counter.hpp"
#include "host/io/scan.hpp"
#include "host/recognize/recognizer.hpp"
#include "support/polyhedra_catalog.hpp"

namespace {

using fs::host::ScanLimits;
using fs::host::rec::RecognizeParams;
using fs::host::rec::Recognizer;

// Heap bytes requested (all threads) while a recognizer for `cells` cells is constructed.
std::uint64_t requested(const RecognizeParams& params, std::size_t cells) {
  const fs::host::Library& library = fs::test::polyhedra_catalog().library;  // built before the count
  const std::uint64_t before = fs::AllocCounter::process_totals().bytes;
  Recognizer r(library, params, cells);
  return fs::AllocCounter::process_totals().bytes - before;
}

TEST(RecognizerMemory, TheBudgetModelCoversWhatTheRecognizerRequestsPerCell) {
  constexpr std::size_t kSmall = std::size_t{1} << 17, kLarge = std::size_t{1} << 18;
  for (int threads : {1, 2}) {
    for (int row_step : {1, 2}) {
      RecognizeParams params;
      params.threads = threads;
      params.segment_row_step = row_step;
      const std::uint64_t small = requested(params, kSmall), large = requested(params, kLarge);
      ASSERT_GT(large, small);
      const double per_cell = static_cast<double>(large - small) / static_cast<double>(kLarge - kSmall);
      const auto model = static_cast<double>(ScanLimits::recognizer_bytes_per_cell(
          static_cast<std::uint32_t>(threads), static_cast<std::uint32_t>(row_step)));
      EXPECT_LE(per_cell, model) << threads << " thread(s), row step " << row_step;
      EXPECT_GE(per_cell, 0.85 * model) << threads << " thread(s), row step " << row_step;
    }
  }
}

}  // namespace
