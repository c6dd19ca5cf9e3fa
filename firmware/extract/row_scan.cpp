#include "firmware/extract/row_scan.hpp"

#include <cstring>

#if defined(__x86_64__)
#include <immintrin.h>
#define FS_SCAN_X86 1
#endif

namespace fs::fw::detail {

#if FS_SCAN_X86
namespace {

// The rows' last partial block, zero-padded (zeros change neither max nor sum).
inline const std::uint8_t* padded_tail(const std::uint8_t* row, std::uint32_t n, std::uint32_t full,
                                       std::uint8_t (&tail)[kBlock]) {
  std::memset(tail, 0, kBlock);
  std::memcpy(tail, row + static_cast<std::size_t>(full) * kBlock, n - full * kBlock);
  return tail;
}

inline std::uint8_t hmax16(__m128i v) {
  v = _mm_max_epu8(v, _mm_srli_si128(v, 8));
  v = _mm_max_epu8(v, _mm_srli_si128(v, 4));
  v = _mm_max_epu8(v, _mm_srli_si128(v, 2));
  v = _mm_max_epu8(v, _mm_srli_si128(v, 1));
  return static_cast<std::uint8_t>(_mm_cvtsi128_si32(v) & 0xff);
}

inline __m128i sse2_block(const std::uint8_t* p, std::uint8_t* lanes, __m128i& acc, __m128i gm) {
  const __m128i z = _mm_setzero_si128();
  const __m128i a0 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p));
  const __m128i a1 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p + 16));
  const __m128i a2 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p + 32));
  const __m128i a3 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p + 48));
  const __m128i m0 = _mm_max_epu8(a0, a2), m1 = _mm_max_epu8(a1, a3);  // lanes j: max(p[j], p[j + 32])
  _mm_storeu_si128(reinterpret_cast<__m128i*>(lanes), m0);
  _mm_storeu_si128(reinterpret_cast<__m128i*>(lanes + 16), m1);
  acc = _mm_add_epi64(acc, _mm_add_epi64(_mm_add_epi64(_mm_sad_epu8(a0, z), _mm_sad_epu8(a1, z)),
                                         _mm_add_epi64(_mm_sad_epu8(a2, z), _mm_sad_epu8(a3, z))));
  return _mm_max_epu8(gm, _mm_max_epu8(m0, m1));
}

void scan_sse2(const std::uint8_t* row, std::uint32_t n, RowScan<std::uint8_t>& s) {
  const std::uint32_t full = n / kBlock;
  __m128i acc = _mm_setzero_si128(), gm = _mm_setzero_si128();
  for (std::uint32_t b = 0; b < full; ++b)
    gm = sse2_block(row + static_cast<std::size_t>(b) * kBlock, s.lane_max[b], acc, gm);
  if (full < s.nblocks) {
    std::uint8_t tail[kBlock];
    gm = sse2_block(padded_tail(row, n, full, tail), s.lane_max[full], acc, gm);
  }
  s.max = hmax16(gm);
  s.sum = static_cast<std::uint64_t>(_mm_cvtsi128_si64(acc)) +
          static_cast<std::uint64_t>(_mm_cvtsi128_si64(_mm_unpackhi_epi64(acc, acc)));
}

__attribute__((target("avx2"))) inline __m256i avx2_block(const std::uint8_t* p, std::uint8_t* lanes,
                                                          __m256i& acc, __m256i gm) {
  const __m256i z = _mm256_setzero_si256();
  const __m256i a0 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p));
  const __m256i a1 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p + 32));
  const __m256i m = _mm256_max_epu8(a0, a1);  // lanes j: max(p[j], p[j + 32])
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(lanes), m);
  acc = _mm256_add_epi64(acc, _mm256_add_epi64(_mm256_sad_epu8(a0, z), _mm256_sad_epu8(a1, z)));
  return _mm256_max_epu8(gm, m);
}

__attribute__((target("avx2"))) void scan_avx2(const std::uint8_t* row, std::uint32_t n,
                                               RowScan<std::uint8_t>& s) {
  const std::uint32_t full = n / kBlock;
  __m256i acc = _mm256_setzero_si256(), gm = _mm256_setzero_si256();
  for (std::uint32_t b = 0; b < full; ++b)
    gm = avx2_block(row + static_cast<std::size_t>(b) * kBlock, s.lane_max[b], acc, gm);
  if (full < s.nblocks) {
    std::uint8_t tail[kBlock];
    gm = avx2_block(padded_tail(row, n, full, tail), s.lane_max[full], acc, gm);
  }
  s.max = hmax16(_mm_max_epu8(_mm256_castsi256_si128(gm), _mm256_extracti128_si256(gm, 1)));
  const __m128i a = _mm_add_epi64(_mm256_castsi256_si128(acc), _mm256_extracti128_si256(acc, 1));
  s.sum = static_cast<std::uint64_t>(_mm_cvtsi128_si64(a)) +
          static_cast<std::uint64_t>(_mm_cvtsi128_si64(_mm_unpackhi_epi64(a, a)));
}

// max_outside_u8 on AVX2: the (at most two) blocks that [lo, hi] overlaps get lane maxima of their samples
// outside [lo, hi] (masked reads of the row), written over theirs in s.lane_max, then every block's lane
// maxima in one pass of fixed length (the same trip count for every row of a frame: no mispredicted exits).
__attribute__((target("avx2"))) std::uint8_t max_outside_avx2(const std::uint8_t* row,
                                                              RowScan<std::uint8_t>& s, std::int64_t lo,
                                                              std::int64_t hi, std::uint32_t blo,
                                                              std::uint32_t bhi) {
  const __m256i iota0 = _mm256_setr_epi8(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19,
                                         20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31);
  const __m256i iota1 = _mm256_add_epi8(iota0, _mm256_set1_epi8(32));
  for (std::uint32_t b = blo; b <= bhi; ++b) {
    const std::int64_t base = static_cast<std::int64_t>(b) * kBlock;
    const __m256i rlo = _mm256_set1_epi8(static_cast<char>(std::clamp<std::int64_t>(lo - base, -1, kBlock)));
    const __m256i rhi = _mm256_set1_epi8(static_cast<char>(std::clamp<std::int64_t>(hi - base, -1, kBlock)));
    // outside [lo, hi]: i < lo or i > hi (indices and bounds in -1 .. 64: signed byte compares are exact)
    const __m256i out0 = _mm256_or_si256(_mm256_cmpgt_epi8(rlo, iota0), _mm256_cmpgt_epi8(iota0, rhi));
    const __m256i out1 = _mm256_or_si256(_mm256_cmpgt_epi8(rlo, iota1), _mm256_cmpgt_epi8(iota1, rhi));
    const __m256i a0 =
        _mm256_and_si256(out0, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(row + base)));
    const __m256i a1 =
        _mm256_and_si256(out1, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(row + base + 32)));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(s.lane_max[b]), _mm256_max_epu8(a0, a1));
  }
  __m256i m0 = _mm256_setzero_si256(), m1 = _mm256_setzero_si256();
  std::uint32_t b = 0;
  for (; b + 1 < s.nblocks; b += 2) {
    m0 = _mm256_max_epu8(m0, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(s.lane_max[b])));
    m1 = _mm256_max_epu8(m1, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(s.lane_max[b + 1])));
  }
  if (b < s.nblocks)
    m0 = _mm256_max_epu8(m0, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(s.lane_max[b])));
  m0 = _mm256_max_epu8(m0, m1);
  return hmax16(_mm_max_epu8(_mm256_castsi256_si128(m0), _mm256_extracti128_si256(m0, 1)));
}

enum class Isa { Sse2, Avx2 };
Isa isa() {
  static const Isa detected = [] {  // once (thread-safe, no allocation)
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") ? Isa::Avx2 : Isa::Sse2;
  }();
  return detected;
}

}  // namespace

bool cpu_has_avx2() { return isa() == Isa::Avx2; }

bool cpu_has_avx512vl() {
  static const bool detected = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
           __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw");
  }();
  return detected;
}

std::uint8_t max_outside_u8(const std::uint8_t* row, RowScan<std::uint8_t>& s, std::int64_t lo,
                            std::int64_t hi) {
  const std::int64_t n = s.n;
  const std::int64_t l = std::clamp<std::int64_t>(lo, 0, n - 1), h = std::clamp<std::int64_t>(hi, l, n - 1);
  const std::uint32_t blo = static_cast<std::uint32_t>(l / kBlock),
                      bhi = static_cast<std::uint32_t>(h / kBlock);
  if (isa() == Isa::Avx2 && bhi <= blo + 1 && static_cast<std::int64_t>(bhi + 1) * kBlock <= n)
    return max_outside_avx2(row, s, l, h, blo, bhi);
  return max_outside<std::uint8_t, 1>(row, s, lo, hi);
}

const char* scan_row_u8_isa() { return isa() == Isa::Avx2 ? "avx2" : "sse2"; }

void scan_row_u8(const std::uint8_t* row, std::uint32_t n, RowScan<std::uint8_t>& s) {
  n = std::min(n, kMaxBlocks * kBlock);
  s.n = n;
  s.nblocks = (n + kBlock - 1) / kBlock;
  if (isa() == Isa::Avx2)
    scan_avx2(row, n, s);
  else
    scan_sse2(row, n, s);
}

#else

bool cpu_has_avx2() { return false; }
bool cpu_has_avx512vl() { return false; }

const char* scan_row_u8_isa() { return "portable"; }

std::uint8_t max_outside_u8(const std::uint8_t* row, RowScan<std::uint8_t>& s, std::int64_t lo,
                            std::int64_t hi) {
  return max_outside<std::uint8_t, 1>(row, s, lo, hi);
}

void scan_row_u8(const std::uint8_t* row, std::uint32_t n, RowScan<std::uint8_t>& s) {
  scan_row_portable<std::uint8_t, 1>(row, n, s);
}

#endif

}  // namespace fs::fw::detail
