// Measures the heap one scan's processing reserves, to check the memory-budget model of ScanLimits
// (host/io/scan.hpp, docs/host-pipeline.md#memory-budget): malloc's own count of allocated bytes
// (mallinfo2: arena + mmapped blocks) before and after constructing each piece.
//
//   build/bin/bench_scan_memory [library meshes...]   (default: hw-sim/scenes/meshes)
//
// Prints, per piece, the bytes measured and the model's estimate: Scan storage, Triangulator (ray table +
// planes), OrganizedCloud, and the Recognizer for N cells (1 thread and all cores), then the Recognizer's
// bytes per cell (slope between two sizes) and its fixed part, and per cell with every other row segmented
// (RecognizeParams::segment_row_step 2).
#include <malloc.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "common/calibration.hpp"
#include "host/io/scan.hpp"
#include "host/io/triangulate.hpp"
#include "host/library/mesh_files.hpp"
#include "host/recognize/recognizer.hpp"
#include "synth_scan.hpp"

namespace {

std::uint64_t heap_bytes() {
  const struct mallinfo2 m = mallinfo2();
  return m.uordblks + m.hblkhd;
}

std::uint64_t rss_bytes() {
  std::ifstream f("/proc/self/statm");
  std::uint64_t size = 0, resident = 0;
  f >> size >> resident;
  return resident * static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
}

double mib(std::uint64_t b) { return double(b) / (1024.0 * 1024.0); }

// Measured in a forked child (a fresh heap state for each size: the parent's freed blocks and arenas do not
// blur the count).
std::uint64_t recognizer_bytes(const fs::host::Library& lib, int threads, std::size_t cells,
                               int row_step = 1) {
  int fd[2];
  if (::pipe(fd) != 0) return 0;
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fd[0]);
    fs::host::rec::RecognizeParams params;
    params.threads = threads;
    params.segment_row_step = row_step;
    const std::uint64_t before = heap_bytes();
    auto r = std::make_unique<fs::host::rec::Recognizer>(lib, params, cells);
    const std::uint64_t bytes = heap_bytes() - before;
    const ssize_t n = ::write(fd[1], &bytes, sizeof bytes);
    ::_exit(n == sizeof bytes ? 0 : 1);
  }
  ::close(fd[1]);
  std::uint64_t bytes = 0;
  const ssize_t n = ::read(fd[0], &bytes, sizeof bytes);
  ::close(fd[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  return n == sizeof bytes ? bytes : 0;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace fs::host;
  std::vector<std::string> inputs;
  for (int i = 1; i < argc; ++i) inputs.emplace_back(argv[i]);
  if (inputs.empty()) inputs.emplace_back(FACETSCAN_SOURCE_DIR "/hw-sim/scenes/meshes");
  const Library lib = load_or_build_library(inputs);

  const auto calib = fs::ScannerCalibration::bench_default(500);
  const std::uint32_t steps = calib.step_count, rows = calib.camera.height, cols = calib.camera.width;
  const std::uint64_t cells = std::uint64_t(steps) * rows;
  std::printf("normal hw-sim scan: %u steps x %u rows x %u cols, %llu cells, %llu points (1 per row)\n",
              steps, rows, cols, static_cast<unsigned long long>(cells),
              static_cast<unsigned long long>(cells));
  std::printf("%-34s %12s %12s\n", "piece", "measured MiB", "model MiB");

  {
    const std::uint64_t b = heap_bytes();
    Scan scan;
    scan.reserve(steps, cells);
    std::printf("%-34s %12.2f %12.2f\n", "Scan (slots + points)", mib(heap_bytes() - b),
                mib(ScanLimits::scan_storage_bytes(steps, cells)));
  }
  {
    const std::uint64_t b = heap_bytes();
    Triangulator tri(calib);
    std::printf("%-34s %12.2f %12.2f\n", "Triangulator (rays + planes)", mib(heap_bytes() - b),
                mib(ScanLimits::triangulator_bytes(steps, rows, cols)));
  }
  {
    const std::uint64_t b = heap_bytes();
    OrganizedCloud cloud;
    Triangulator tri(calib);
    const std::uint64_t t = heap_bytes();
    tri.begin(cloud);
    std::printf("%-34s %12.2f %12.2f\n", "OrganizedCloud", mib(heap_bytes() - t),
                mib(cells * ScanLimits::kCloudBytesPerCell));
    (void)b;
  }
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  for (int threads : {1, cores, 16}) {
    const std::size_t n1 = 1u << 20, n2 = 1u << 22;
    const std::uint64_t b1 = recognizer_bytes(lib, threads, n1);
    const std::uint64_t b2 = recognizer_bytes(lib, threads, n2);
    const double per_cell = double(b2 - b1) / double(n2 - n1);
    const double fixed = double(b1) - per_cell * double(n1);
    const std::uint64_t bn = recognizer_bytes(lib, threads, cells);
    const auto t = static_cast<std::uint32_t>(threads);
    std::printf("%-34s %12.2f %12.2f   (%d threads)\n", "Recognizer for the scan's cells", mib(bn),
                mib(ScanLimits::recognizer_bytes(cells, t) + ScanLimits::fixed_bytes(t)), threads);
    std::printf(
        "  Recognizer: %.1f bytes per cell, %.1f MiB fixed (%d threads; model %llu B/cell, %.1f MiB)\n",
        per_cell, fixed / (1024.0 * 1024.0), threads,
        static_cast<unsigned long long>(ScanLimits::recognizer_bytes_per_cell(t)),
        mib(ScanLimits::fixed_bytes(t)));
  }
  {
    const std::size_t n1 = 1u << 20, n2 = 1u << 22;
    const std::uint64_t b1 = recognizer_bytes(lib, 1, n1, 2), b2 = recognizer_bytes(lib, 1, n2, 2);
    std::printf(
        "  Recognizer, every other row segmented (segment_row_step 2): %.1f bytes per cell (1 thread)\n",
        double(b2 - b1) / double(n2 - n1));
  }
  // Resident memory a real recognize() touches: a flat-target scan of 500 and 2000 steps (1024 rows),
  // triangulated, then a Recognizer (1 thread) constructed for its cells and run on it.
  for (std::uint32_t n_steps : {500u, 2000u}) {
    const auto c = fs::ScannerCalibration::bench_default(n_steps);
    const auto synth = fs::test::synth_flat_scan(c, c, 20.0, 0.05, 1);
    Scan scan;
    fs::test::fill_scan(synth, scan);
    OrganizedCloud cloud;
    Triangulator(c).triangulate(scan, cloud);
    malloc_trim(0);  // what earlier pieces freed goes back first
    const std::uint64_t before = rss_bytes();
    fs::host::rec::RecognizeParams params;
    params.threads = 1;
    fs::host::rec::Recognizer r(lib, params, cloud.points.size());
    r.recognize(cloud);
    const std::uint64_t after = rss_bytes();
    std::printf("recognize() of a %u x 1024 flat scan: resident +%.1f MiB = %.1f bytes per cell (1 thread)\n",
                n_steps, mib(after - before), double(after - before) / double(cloud.points.size()));
  }
  const ScanLimits defaults;
  std::printf(
      "model total for the normal scan: %.1f MiB of the default budget %.0f MiB (%u threads); "
      "default limits: %llu cells, %llu ray-table entries, %llu stripe points\n",
      mib(defaults.bytes(steps, rows, cols, cells)), mib(defaults.budget_bytes), defaults.threads,
      static_cast<unsigned long long>(defaults.max_cells),
      static_cast<unsigned long long>(defaults.max_ray_table_entries),
      static_cast<unsigned long long>(defaults.max_total_points));
  return 0;
}
