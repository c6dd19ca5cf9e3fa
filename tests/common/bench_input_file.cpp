// bench_input_file: what reading a large file into memory costs where page faults are expensive.
//  * BM_TouchFreshMemory/huge:0|1: first touch of 64 MiB of fresh anonymous memory, 4 KB pages or advised for
//    transparent huge pages (MADV_HUGEPAGE); counter us_per_4k_page.
//  * BM_ReadFile/way:0|1: a 32 MiB file (in the page cache) read whole: 0 into a zero-filled std::vector (how
//    read_input_bytes read before), 1 through read_input_bytes (fs::ByteBuffer: own mapping, huge pages, no
//    fill).
// Each iteration maps or allocates anew, so every iteration pays the first touch, as a fresh process does.
#include <benchmark/benchmark.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <filesystem>
#include <fstream>
#include <vector>

#include "common/input_file.hpp"

namespace {

constexpr std::size_t kTouchBytes = std::size_t{64} << 20;
constexpr std::size_t kFileBytes = std::size_t{32} << 20;

void BM_TouchFreshMemory(benchmark::State& state) {
  const bool huge = state.range(0) != 0;
  for (auto _ : state) {
    void* p = ::mmap(nullptr, kTouchBytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) {
      state.SkipWithError("mmap failed");
      break;
    }
    if (huge) ::madvise(p, kTouchBytes, MADV_HUGEPAGE);
    auto* b = static_cast<volatile char*>(p);
    for (std::size_t i = 0; i < kTouchBytes; i += 4096) b[i] = 1;
    ::munmap(p, kTouchBytes);
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * kTouchBytes));
  // Millions of pages per second, inverted: microseconds per page.
  state.counters["us_per_4k_page"] =
      benchmark::Counter(static_cast<double>(state.iterations() * (kTouchBytes / 4096)) / 1e6,
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_TouchFreshMemory)->ArgName("huge")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

std::filesystem::path g_sample;  // removed at exit when made

const std::filesystem::path& sample_file() {
  static const std::filesystem::path path = [] {
    const auto p =
        std::filesystem::temp_directory_path() / ("facetscan-bench-read-" + std::to_string(::getpid()));
    std::vector<char> chunk(1 << 20);
    for (std::size_t i = 0; i < chunk.size(); ++i) chunk[i] = static_cast<char>(i * 131);
    std::ofstream f(p, std::ios::binary);
    for (std::size_t n = 0; n < kFileBytes; n += chunk.size())
      f.write(chunk.data(), static_cast<long>(chunk.size()));
    g_sample = p;
    return p;
  }();
  return path;
}

void BM_ReadFile(benchmark::State& state) {
  const auto& path = sample_file();
  for (auto _ : state) {
    if (state.range(0) == 0) {
      std::vector<std::byte> v(kFileBytes);
      const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
      std::size_t got = 0;
      while (got < v.size()) {
        const ssize_t r = ::read(fd, v.data() + got, v.size() - got);
        if (r <= 0) break;
        got += static_cast<std::size_t>(r);
      }
      ::close(fd);
      benchmark::DoNotOptimize(v.data());
    } else {
      const fs::ByteBuffer b = fs::read_input_bytes(path, fs::kMaxLibraryFileBytes, "bench file");
      benchmark::DoNotOptimize(b.data());
    }
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * kFileBytes));
}
BENCHMARK(BM_ReadFile)->ArgName("way")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  if (!g_sample.empty()) std::filesystem::remove(g_sample);
  return 0;
}
