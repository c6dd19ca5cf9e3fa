#pragma once
// Returning memory after a scan larger than the usual working size (ScanLimits, the budget model, is in
// host/io/scan.hpp).
#include <cstdint>

#include "host/io/organized_cloud.hpp"
#include "host/io/scan.hpp"
#include "host/io/triangulate.hpp"

namespace fs::host {

// The scan size whose storage is kept warm between scans: the normal hw-sim scan.
struct WorkingSize {
  std::uint32_t steps = 500;
  std::uint32_t rows = 1024;
  std::uint32_t cols = 1280;
};

// Call after a delivered scan has been processed (its Scan, cloud and results are no longer used): frees
// what the Scan's storage (Scan::release_storage), the Triangulator's tables (Triangulator::release) and
// `cloud` (may be null) hold beyond a scan of `keep` (one point per cell), then malloc_trim(0) so that the
// pages go back to the system. Returns the bytes freed; 0 (and no allocation, no trim) after a scan within
// the working size. A released Triangulator reconfigures itself on its next triangulate(); a released
// Scan or cloud may be emptied. The Recognizer's per-cell buffers are not covered (recreate it).
std::uint64_t release_scan_memory(Scan& scan, Triangulator& triangulator, OrganizedCloud* cloud,
                                  const WorkingSize& keep = {});

}  // namespace fs::host
