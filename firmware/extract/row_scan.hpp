#pragma once
// The one full pass over an image row that stripe extraction makes: per block of 64 samples the lane-wise
// maxima (kLanes lanes, each the max of the block's samples j and j + kLanes) and the row sum. Written as
// plain fixed-trip-count loops over independent lanes so the compiler vectorizes them on every target (SSE2 /
// AVX2 on x86-64, NEON on aarch64/armhf) without intrinsics; no horizontal reduction per block. Everything
// after this pass (arg-max, support, background, double-peak test, sub-pixel fit) touches only the few
// samples around the peak plus these block maxima.
//
// 8-bit rows (Mono8, the hot case) on x86-64 take the SIMD path of row_scan.cpp instead: the same lane maxima
// with the row sum by PSADBW (the compiler cannot derive a byte sum that cheap), AVX2 when the CPU has it,
// else SSE2 (part of x86-64). Both are faster than the auto-vectorized loop (bench_extract
// --benchmark_filter=ScanRow). Both give bit-identical results (tests/firmware/extract_scan_test.cpp); every
// other target and sample type uses the portable loop.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <type_traits>

namespace fs::fw::detail {

constexpr std::uint32_t kBlock = 64;       // samples per block
constexpr std::uint32_t kLanes = 32;       // lane maxima kept per block (kBlock / 2)
constexpr std::uint32_t kMaxBlocks = 256;  // rows up to 16384 samples

template <typename T>
struct RowScan {
  // Lane accumulator of the sum: 8-bit samples add up in 16-bit lanes (2 x 255 per block, flushed every 64
  // blocks), 16-bit samples in 32-bit lanes.
  using Acc = std::conditional_t<sizeof(T) == 1, std::uint16_t, std::uint32_t>;
  static constexpr std::uint32_t kFlushBlocks = sizeof(T) == 1 ? 64 : kMaxBlocks;

  T lane_max[kMaxBlocks][kLanes];  // per block, lane-wise maxima (uninitialized beyond nblocks)
  std::uint32_t nblocks = 0;
  std::uint32_t n = 0;  // samples scanned (the row width, clamped to kMaxBlocks * kBlock)
  std::uint64_t sum = 0;
  T max = 0;

  // Max of block b (horizontal over its lanes).
  T block_max(std::uint32_t b) const {
    T m = 0;
    for (std::uint32_t j = 0; j < kLanes; ++j) m = lane_max[b][j] > m ? lane_max[b][j] : m;
    return m;
  }
};

// One block: lane maxima and lane sums. Step is the sample spacing (2 = the luma of YUYV).
template <typename T, std::uint32_t Step, typename Acc>
inline void scan_block(const T* __restrict p, T* __restrict lane_max, Acc* __restrict acc) {
  for (std::uint32_t j = 0; j < kLanes; ++j) {
    const T a = p[j * Step], c = p[(j + kLanes) * Step];
    lane_max[j] = a > c ? a : c;
    acc[j] = static_cast<Acc>(acc[j] + a + c);
  }
}

// The portable pass (any T, Step).
template <typename T, std::uint32_t Step>
void scan_row_portable(const T* row, std::uint32_t n, RowScan<T>& s) {
  using Acc = typename RowScan<T>::Acc;
  n = std::min(n, kMaxBlocks * kBlock);
  s.n = n;
  s.nblocks = (n + kBlock - 1) / kBlock;
  const std::uint32_t full = n / kBlock;
  alignas(64) Acc acc[kLanes] = {};
  std::uint64_t sum = 0;
  const auto flush = [&] {
    for (std::uint32_t j = 0; j < kLanes; ++j) {
      sum += acc[j];
      acc[j] = 0;
    }
  };
  for (std::uint32_t b = 0; b < full; ++b) {
    scan_block<T, Step>(row + static_cast<std::size_t>(b) * kBlock * Step, s.lane_max[b], acc);
    if ((b + 1) % RowScan<T>::kFlushBlocks == 0) flush();
  }
  if (full < s.nblocks) {  // the partial last block, zero-padded (zeros change neither max nor sum)
    T tail[kBlock] = {};
    for (std::uint32_t i = full * kBlock; i < n; ++i)
      tail[i - full * kBlock] = row[static_cast<std::size_t>(i) * Step];
    scan_block<T, 1>(tail, s.lane_max[full], acc);
  }
  flush();
  alignas(64) T mx[kLanes] = {};
  for (std::uint32_t b = 0; b < s.nblocks; ++b)
    for (std::uint32_t j = 0; j < kLanes; ++j) mx[j] = s.lane_max[b][j] > mx[j] ? s.lane_max[b][j] : mx[j];
  T m = 0;
  for (std::uint32_t j = 0; j < kLanes; ++j) m = mx[j] > m ? mx[j] : m;
  s.max = m;
  s.sum = sum;
}

// True on x86-64 CPUs with AVX2, resp. AVX-512 F + VL + DQ + BW (detected once); false on every other target.
bool cpu_has_avx2();
bool cpu_has_avx512vl();

// Which implementation scan_row uses for 8-bit rows: "avx2", "sse2" or "portable".
const char* scan_row_u8_isa();
// The 8-bit pass with the best instruction set of this CPU (row_scan.cpp).
void scan_row_u8(const std::uint8_t* row, std::uint32_t n, RowScan<std::uint8_t>& s);

template <typename T, std::uint32_t Step>
inline void scan_row(const T* row, std::uint32_t n, RowScan<T>& s) {
  if constexpr (sizeof(T) == 1 && Step == 1)
    scan_row_u8(row, n, s);
  else
    scan_row_portable<T, Step>(row, n, s);
}

// Max of the samples [begin, end) (exact; vectorizable for Step 1).
template <typename T, std::uint32_t Step>
inline T range_max(const T* row, std::int64_t begin, std::int64_t end) {
  T m = 0;
  for (std::int64_t i = begin; i < end; ++i) {
    const T v = row[static_cast<std::size_t>(i) * Step];
    m = v > m ? v : m;
  }
  return m;
}

// Max of every sample outside [lo, hi] (inclusive): lane maxima for the blocks clear of it, exact scans of
// the parts of the (at most few) blocks it overlaps. Generic vectors of one block's kLanes lane maxima
// (SSE2/AVX2 on x86-64, NEON on arm); for contiguous rows (Step 1) the overlapped full blocks are read whole
// with the samples inside [lo, hi] masked out, no per-sample loop.
template <typename T>
struct Vec16;  // 16 bytes of T as a generic vector (the SIMD width every target has), and its signed twin
template <>
struct Vec16<std::uint8_t> {
  using V = std::uint8_t __attribute__((vector_size(16)));
  using VS = std::int8_t __attribute__((vector_size(16)));
};
template <>
struct Vec16<std::uint16_t> {
  using V = std::uint16_t __attribute__((vector_size(16)));
  using VS = std::int16_t __attribute__((vector_size(16)));
};

template <typename T, std::uint32_t Step>
T max_outside(const T* row, const RowScan<T>& s, std::int64_t lo, std::int64_t hi) {
  using V = typename Vec16<T>::V;
  using VS = typename Vec16<T>::VS;
  using ST = std::make_signed_t<T>;
  constexpr std::uint32_t kW = 16 / sizeof(T), kParts = kLanes / kW;  // samples per vector, vectors per block
  const std::int64_t n = s.n;
  lo = std::clamp<std::int64_t>(lo, 0, n - 1);
  hi = std::clamp<std::int64_t>(hi, lo, n - 1);
  const std::uint32_t blo = static_cast<std::uint32_t>(lo / kBlock),
                      bhi = static_cast<std::uint32_t>(hi / kBlock);
  V mx[kParts] = {};
  const auto vmax = [](V a, V b) { return a > b ? a : b; };
  const auto add_blocks = [&](std::uint32_t b0, std::uint32_t b1) {
    for (std::uint32_t b = b0; b < b1; ++b) {
      for (std::uint32_t q = 0; q < kParts; ++q) {
        V v;
        __builtin_memcpy(&v, s.lane_max[b] + q * kW, sizeof v);
        mx[q] = vmax(mx[q], v);
      }
    }
  };
  add_blocks(0, blo);
  add_blocks(bhi + 1, s.nblocks);
  if constexpr (Step == 1) {
    if (static_cast<std::int64_t>(bhi + 1) * kBlock <= n) {  // the overlapped blocks are full: masked reads
      VS iota;
      for (std::uint32_t j = 0; j < kW; ++j) iota[j] = static_cast<ST>(j);
      for (std::uint32_t b = blo; b <= bhi; ++b) {
        const std::int64_t base = static_cast<std::int64_t>(b) * kBlock;
        const VS rlo = VS{} + static_cast<ST>(std::clamp<std::int64_t>(lo - base, -1, kBlock));
        const VS rhi = VS{} + static_cast<ST>(std::clamp<std::int64_t>(hi - base, -1, kBlock));
        for (std::uint32_t h = 0; h < kBlock; h += kW) {
          V v;
          __builtin_memcpy(&v, row + base + h, sizeof v);
          const VS id = iota + static_cast<ST>(h);
          const V keep = reinterpret_cast<const V&>(static_cast<const VS&>((id < rlo) | (id > rhi)));
          mx[0] = vmax(mx[0], v & keep);
        }
      }
      T m = 0;
      for (std::uint32_t q = 1; q < kParts; ++q) mx[0] = vmax(mx[0], mx[q]);
      for (std::uint32_t j = 0; j < kW; ++j) m = mx[0][j] > m ? mx[0][j] : m;
      return m;
    }
  }
  for (std::uint32_t q = 1; q < kParts; ++q) mx[0] = vmax(mx[0], mx[q]);
  T m = 0;
  for (std::uint32_t j = 0; j < kW; ++j) m = mx[0][j] > m ? mx[0][j] : m;
  const T left = range_max<T, Step>(row, static_cast<std::int64_t>(blo) * kBlock, lo);
  const T right =
      range_max<T, Step>(row, hi + 1, std::min<std::int64_t>(static_cast<std::int64_t>(bhi + 1) * kBlock, n));
  m = left > m ? left : m;
  return right > m ? right : m;
}

// max_outside for contiguous 8-bit rows, the same result: on x86-64 with AVX2 it overwrites the lane maxima
// of the (at most two) blocks that [lo, hi] overlaps with those of their samples outside [lo, hi], so s is
// spent for any other window afterwards (what extraction does: one double-peak test per row pass).
std::uint8_t max_outside_u8(const std::uint8_t* row, RowScan<std::uint8_t>& s, std::int64_t lo,
                            std::int64_t hi);

}  // namespace fs::fw::detail
