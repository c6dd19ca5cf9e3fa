#pragma once
// The walks around a row's peak as bit masks (x86-64 with AVX2 + BMI1/LZCNT, picked at run time by
// stripe_extractor.cpp): the 64 samples at imax - 32 .. imax + 31 (zeros outside the row, as in
// row_lanes.hpp's LaneWindow::raw) compared with a threshold in two 32-byte vectors give a 64-bit mask, bit x
// = sample imax - 32 + x above the threshold; a walk from imax is then a count of ones (std::countl_one
// leftward from bit 31, std::countr_one rightward from bit 33), capped where the walks of row_lanes.hpp stop.
// Same counts as those walks and the per-row walks (tests/firmware/extract_lanes_test.cpp), one row at a time
// without branches.
#if defined(__x86_64__)
#include <immintrin.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>

#include "firmware/extract/row_scan.hpp"

#define FS_ROW_MASKS_TARGET __attribute__((target("avx2,bmi,lzcnt")))

namespace fs::fw::detail::masks {

struct Window {
  __m256i lo, hi;  // samples imax - 32 .. imax - 1 and imax .. imax + 31
};

FS_ROW_MASKS_TARGET inline Window load(const std::uint8_t* raw) {
  return {_mm256_loadu_si256(reinterpret_cast<const __m256i*>(raw)),
          _mm256_loadu_si256(reinterpret_cast<const __m256i*>(raw + 32))};
}

FS_ROW_MASKS_TARGET inline void store(std::uint8_t* raw, const Window& w) {
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(raw), w.lo);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(raw + 32), w.hi);
}

// Bit x: sample x > t (unsigned bytes: not v <= t, i.e. min(v, t) != v).
FS_ROW_MASKS_TARGET inline std::uint64_t above(const Window& w, int t) {
  const __m256i tv = _mm256_set1_epi8(static_cast<char>(t));
  const auto le_lo =
      static_cast<std::uint32_t>(_mm256_movemask_epi8(_mm256_cmpeq_epi8(_mm256_min_epu8(w.lo, tv), w.lo)));
  const auto le_hi =
      static_cast<std::uint32_t>(_mm256_movemask_epi8(_mm256_cmpeq_epi8(_mm256_min_epu8(w.hi, tv), w.hi)));
  return ~(static_cast<std::uint64_t>(le_lo) | static_cast<std::uint64_t>(le_hi) << 32);
}

// Bit x: sample x == t.
FS_ROW_MASKS_TARGET inline std::uint64_t equal(const Window& w, int t) {
  const __m256i tv = _mm256_set1_epi8(static_cast<char>(t));
  return static_cast<std::uint64_t>(
             static_cast<std::uint32_t>(_mm256_movemask_epi8(_mm256_cmpeq_epi8(w.lo, tv)))) |
         static_cast<std::uint64_t>(
             static_cast<std::uint32_t>(_mm256_movemask_epi8(_mm256_cmpeq_epi8(w.hi, tv))))
             << 32;
}

// Contiguous set bits of m left of imax (from bit 31 down) and right of it (from bit 33 up), at most cap
// each.
FS_ROW_MASKS_TARGET inline int run_left(std::uint64_t m, int cap) {
  return std::min(std::countl_one(m << 32), cap);
}
FS_ROW_MASKS_TARGET inline int run_right(std::uint64_t m, int cap) {
  return std::min(std::countr_one(m >> 33), cap);
}

// Sum of the samples imax - left .. imax + right without imax itself (bits 32 - left .. 32 + right but 32).
FS_ROW_MASKS_TARGET inline std::int64_t support_sum(const Window& w, int left, int right) {
  const __m256i i0 = _mm256_setr_epi8(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19,
                                      20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31);
  const __m256i i1 = _mm256_add_epi8(i0, _mm256_set1_epi8(32));
  const __m256i a = _mm256_set1_epi8(static_cast<char>(31 - left)),
                b = _mm256_set1_epi8(static_cast<char>(33 + right));
  const __m256i centre = _mm256_set1_epi8(32);
  // index > 31 - left and index < 33 + right, not 32 (indices 0..63: signed compares are exact)
  const __m256i in0 = _mm256_and_si256(_mm256_cmpgt_epi8(i0, a), _mm256_cmpgt_epi8(b, i0));
  const __m256i in1 = _mm256_andnot_si256(
      _mm256_cmpeq_epi8(i1, centre), _mm256_and_si256(_mm256_cmpgt_epi8(i1, a), _mm256_cmpgt_epi8(b, i1)));
  const __m256i z = _mm256_setzero_si256();
  const __m256i s = _mm256_add_epi64(_mm256_sad_epu8(_mm256_and_si256(w.lo, in0), z),
                                     _mm256_sad_epu8(_mm256_and_si256(w.hi, in1), z));
  const __m128i h = _mm_add_epi64(_mm256_castsi256_si128(s), _mm256_extracti128_si256(s, 1));
  return _mm_cvtsi128_si64(_mm_add_epi64(h, _mm_unpackhi_epi64(h, h)));
}

// y[x] = (float(raw[x]) - bg) * inv for x = 0 .. 31 (the batched fit's lane input, defer_to_batch's
// arithmetic).
FS_ROW_MASKS_TARGET inline void fill_lane(const std::uint8_t* raw, float bg, float inv, float* y) {
  const __m256 b = _mm256_set1_ps(bg), iv = _mm256_set1_ps(inv);
  for (int q = 0; q < 4; ++q) {
    const __m128i v8 = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(raw + 8 * q));
    const __m256 f = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(v8));
    _mm256_storeu_ps(y + 8 * q, _mm256_mul_ps(_mm256_sub_ps(f, b), iv));
  }
}

// dst[x][lane] = src[lane][x] for 32 x and 8 lanes (four 8 x 8 float transposes).
FS_ROW_MASKS_TARGET inline void transpose_lanes(const float (*src)[32], float (*dst)[8]) {
  for (int c = 0; c < 32; c += 8) {
    __m256 r[8];
    for (int i = 0; i < 8; ++i) r[i] = _mm256_loadu_ps(src[i] + c);
    const __m256 t0 = _mm256_unpacklo_ps(r[0], r[1]), t1 = _mm256_unpackhi_ps(r[0], r[1]);
    const __m256 t2 = _mm256_unpacklo_ps(r[2], r[3]), t3 = _mm256_unpackhi_ps(r[2], r[3]);
    const __m256 t4 = _mm256_unpacklo_ps(r[4], r[5]), t5 = _mm256_unpackhi_ps(r[4], r[5]);
    const __m256 t6 = _mm256_unpacklo_ps(r[6], r[7]), t7 = _mm256_unpackhi_ps(r[6], r[7]);
    const __m256 u0 = _mm256_shuffle_ps(t0, t2, 0x44), u1 = _mm256_shuffle_ps(t0, t2, 0xEE);
    const __m256 u2 = _mm256_shuffle_ps(t1, t3, 0x44), u3 = _mm256_shuffle_ps(t1, t3, 0xEE);
    const __m256 u4 = _mm256_shuffle_ps(t4, t6, 0x44), u5 = _mm256_shuffle_ps(t4, t6, 0xEE);
    const __m256 u6 = _mm256_shuffle_ps(t5, t7, 0x44), u7 = _mm256_shuffle_ps(t5, t7, 0xEE);
    _mm256_storeu_ps(dst[c + 0], _mm256_permute2f128_ps(u0, u4, 0x20));
    _mm256_storeu_ps(dst[c + 1], _mm256_permute2f128_ps(u1, u5, 0x20));
    _mm256_storeu_ps(dst[c + 2], _mm256_permute2f128_ps(u2, u6, 0x20));
    _mm256_storeu_ps(dst[c + 3], _mm256_permute2f128_ps(u3, u7, 0x20));
    _mm256_storeu_ps(dst[c + 4], _mm256_permute2f128_ps(u0, u4, 0x31));
    _mm256_storeu_ps(dst[c + 5], _mm256_permute2f128_ps(u1, u5, 0x31));
    _mm256_storeu_ps(dst[c + 6], _mm256_permute2f128_ps(u2, u6, 0x31));
    _mm256_storeu_ps(dst[c + 7], _mm256_permute2f128_ps(u3, u7, 0x31));
  }
}

// The first sample equal to the row maximum mx (what memchr(row, mx, n) finds): the first block whose lane
// maxima hold mx (one compare of 32 bytes per block), then that block's 64 samples; a partial last block by
// memchr (nothing is read past the row). Cheaper per frame than memchr from the row start (bench_extract
// --benchmark_filter=Extract).
FS_ROW_MASKS_TARGET inline std::uint32_t first_argmax(const std::uint8_t* row, const RowScan<std::uint8_t>& s,
                                                      std::uint8_t mx) {
  const __m256i m = _mm256_set1_epi8(static_cast<char>(mx));
  std::uint32_t b = 0;
  while (b + 1 < s.nblocks && !_mm256_movemask_epi8(_mm256_cmpeq_epi8(
                                  _mm256_loadu_si256(reinterpret_cast<const __m256i*>(s.lane_max[b])), m)))
    ++b;
  const std::uint32_t base = b * kBlock;
  if (base + kBlock > s.n) {
    const void* hit = std::memchr(row + base, mx, s.n - base);
    return hit ? static_cast<std::uint32_t>(static_cast<const std::uint8_t*>(hit) - row) : 0;
  }
  return base +
         static_cast<std::uint32_t>(std::countr_zero(equal(load(row + base), mx)));  // the block holds mx
}

}  // namespace fs::fw::detail::masks
#endif
