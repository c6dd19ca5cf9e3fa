#pragma once
// The walks around each row's peak for a block of kLaneRows 8-bit rows at once, one row per SIMD lane (int16
// generic vectors of 8 lanes: SSE2 on x86-64, NEON on arm), the way the batched fit (gauss_ml.hpp) works.
//
// Each row's samples at imax - kWinHalf .. imax + kWinHalf - 1 (zeros outside the row) are copied into
// LaneWindow::raw, then transposed so that w[kWinHalf + d][lane] is that lane's sample at imax + d. The walks
// (support of the peak, its flat top, the half-maximum flanks) then step d = 1, 2, ... for all lanes
// together: a lane's walk is a mask that stays set while its condition holds (no per-row branch, one loop
// exit per block instead of one mispredicted exit per row and walk). The zeros outside the row stop every
// walk there exactly where the per-row walks stop at the row's ends (every threshold is >= 0 and the walks
// ask `v > threshold`), so the counts are the per-row walks' (stripe_extractor.cpp uses the per-row code for
// Mono16 and as the reference; tests/firmware/extract_lanes_test.cpp checks they agree).
#include <cstdint>
#include <cstring>

namespace fs::fw::detail {

constexpr int kLaneRows = 8;  // rows per block (= kBatch of the fit)
constexpr int kWinHalf = 32;  // window imax - 32 .. imax + 31: walks of up to kMaxLaneWalk samples + 1 flank
constexpr int kMaxLaneWalk = kWinHalf - 2;

using LaneI16 = std::int16_t __attribute__((vector_size(16)));
using LaneU8 = std::uint8_t __attribute__((vector_size(16)));

struct LaneWindow {
  alignas(64) std::uint8_t raw[kLaneRows][2 * kWinHalf];  // per lane, row-major
  alignas(64) LaneI16 w[2 * kWinHalf];                    // transposed: w[x][lane] = raw[lane][x]
};

// dst[x] = the row's samples at imax - kWinHalf + x (spaced Step apart) for x < 2 kWinHalf, 0 outside [0, n).
template <std::uint32_t Step>
inline void window_fill(std::uint8_t* dst, const std::uint8_t* row, std::uint32_t n, std::uint32_t imax) {
  const std::int64_t first = static_cast<std::int64_t>(imax) - kWinHalf;
  if (Step == 1 && first >= 0 && first + 2 * kWinHalf <= static_cast<std::int64_t>(n)) {
    std::memcpy(dst, row + first, 2 * kWinHalf);
    return;
  }
  for (std::int64_t x = 0; x < 2 * kWinHalf; ++x) {
    const std::int64_t i = first + x;
    dst[x] = (i >= 0 && i < static_cast<std::int64_t>(n)) ? row[static_cast<std::size_t>(i) * Step] : 0;
  }
}

// raw[lane] = the row's window (window_fill).
template <std::uint32_t Step>
inline void lane_window_fill(LaneWindow& win, int lane, const std::uint8_t* row, std::uint32_t n,
                             std::uint32_t imax) {
  window_fill<Step>(win.raw[lane], row, n, imax);
}

namespace lanes {

template <int... I>
inline LaneU8 shuffle(LaneU8 a, LaneU8 b) {
#if defined(__clang__)
  return __builtin_shufflevector(a, b, I...);
#else
  return __builtin_shuffle(a, b, LaneU8{I...});
#endif
}
inline LaneU8 lo8(LaneU8 a, LaneU8 b) {
  return shuffle<0, 16, 1, 17, 2, 18, 3, 19, 4, 20, 5, 21, 6, 22, 7, 23>(a, b);
}
inline LaneU8 hi8(LaneU8 a, LaneU8 b) {
  return shuffle<8, 24, 9, 25, 10, 26, 11, 27, 12, 28, 13, 29, 14, 30, 15, 31>(a, b);
}
inline LaneU8 lo16(LaneU8 a, LaneU8 b) {
  return shuffle<0, 1, 16, 17, 2, 3, 18, 19, 4, 5, 20, 21, 6, 7, 22, 23>(a, b);
}
inline LaneU8 hi16(LaneU8 a, LaneU8 b) {
  return shuffle<8, 9, 24, 25, 10, 11, 26, 27, 12, 13, 28, 29, 14, 15, 30, 31>(a, b);
}
inline LaneU8 lo32(LaneU8 a, LaneU8 b) {
  return shuffle<0, 1, 2, 3, 16, 17, 18, 19, 4, 5, 6, 7, 20, 21, 22, 23>(a, b);
}
inline LaneU8 hi32(LaneU8 a, LaneU8 b) {
  return shuffle<8, 9, 10, 11, 24, 25, 26, 27, 12, 13, 14, 15, 28, 29, 30, 31>(a, b);
}
// The same 16 bytes as another 16-byte vector type.
template <class To, class From>
inline To bits(From a) {
  static_assert(sizeof(To) == sizeof(From));
  To r;
  std::memcpy(&r, &a, sizeof r);
  return r;
}
// The low / high 8 bytes zero-extended to 8 int16 (little-endian lanes): interleaved with zero bytes.
inline LaneI16 widen_lo(LaneU8 a) { return bits<LaneI16>(lo8(a, LaneU8{})); }
inline LaneI16 widen_hi(LaneU8 a) { return bits<LaneI16>(hi8(a, LaneU8{})); }
// The low / high 4 int16 lanes (>= 0) zero-extended to int32: interleaved with zero int16.
using LaneI32 = std::int32_t __attribute__((vector_size(16)));
inline LaneI32 widen32_lo(LaneI16 a) { return bits<LaneI32>(lo16(bits<LaneU8>(a), LaneU8{})); }
inline LaneI32 widen32_hi(LaneI16 a) { return bits<LaneI32>(hi16(bits<LaneU8>(a), LaneU8{})); }
inline bool any(LaneI16 m) {
  std::uint64_t u[2];
  std::memcpy(u, &m, sizeof u);
  return (u[0] | u[1]) != 0;
}

}  // namespace lanes

// w from raw: 8 x 16 bytes at a time through three interleave stages (the byte transpose), then
// zero-extended.
inline void lane_window_transpose(LaneWindow& win) {
  using namespace lanes;
  for (int c = 0; c < 2 * kWinHalf; c += 16) {
    LaneU8 r[kLaneRows];
    for (int i = 0; i < kLaneRows; ++i) std::memcpy(&r[i], win.raw[i] + c, 16);
    const LaneU8 a0 = lo8(r[0], r[1]), a1 = hi8(r[0], r[1]), a2 = lo8(r[2], r[3]), a3 = hi8(r[2], r[3]);
    const LaneU8 a4 = lo8(r[4], r[5]), a5 = hi8(r[4], r[5]), a6 = lo8(r[6], r[7]), a7 = hi8(r[6], r[7]);
    // b: 4 rows x 4 columns; columns 0-3, 4-7 (rows 0-3), the same for rows 4-7, then columns 8-15
    const LaneU8 b0 = lo16(a0, a2), b1 = hi16(a0, a2), b2 = lo16(a4, a6), b3 = hi16(a4, a6);
    const LaneU8 b4 = lo16(a1, a3), b5 = hi16(a1, a3), b6 = lo16(a5, a7), b7 = hi16(a5, a7);
    const LaneU8 q[8] = {lo32(b0, b2), hi32(b0, b2), lo32(b1, b3), hi32(b1, b3),
                         lo32(b4, b6), hi32(b4, b6), lo32(b5, b7), hi32(b5, b7)};  // 2 columns x 8 rows each
    for (int k = 0; k < 8; ++k) {
      win.w[c + 2 * k] = widen_lo(q[k]);
      win.w[c + 2 * k + 1] = widen_hi(q[k]);
    }
  }
}

// The support walks: per lane, how many contiguous samples left / right of imax exceed low[lane] (at most
// max_walk), their sum, and how many samples right of imax within that support are >= top[lane] (the flat
// top). Lanes with low = 32767 walk nowhere.
struct LaneSupport {
  LaneI16 left, right, sum, top;
};
inline LaneSupport lane_support_walks(const LaneWindow& win, LaneI16 low, LaneI16 top, int max_walk) {
  LaneI16 aliveL = ~LaneI16{}, aliveR = ~LaneI16{}, aliveT = ~LaneI16{};
  LaneSupport s{LaneI16{}, LaneI16{}, LaneI16{}, LaneI16{}};
  for (int d = 1; d <= max_walk; ++d) {
    const LaneI16 vl = win.w[kWinHalf - d], vr = win.w[kWinHalf + d];
    aliveL &= vl > low;
    aliveR &= vr > low;
    aliveT &= aliveR & (vr >= top);
    s.left -= aliveL;
    s.right -= aliveR;
    s.top -= aliveT;
    s.sum += (vl & aliveL) + (vr & aliveR);
    if (!lanes::any(aliveL | aliveR)) break;
  }
  return s;
}

// The half-maximum walks inside the support: samples left / right of imax above half[lane], at most
// left_max[lane] / right_max[lane] of them.
inline void lane_half_walks(const LaneWindow& win, LaneI16 half, LaneI16 left_max, LaneI16 right_max,
                            int max_walk, LaneI16& left, LaneI16& right) {
  LaneI16 aliveL = ~LaneI16{}, aliveR = ~LaneI16{};
  left = right = LaneI16{};
  for (int d = 1; d <= max_walk; ++d) {
    const LaneI16 dv = LaneI16{} + static_cast<std::int16_t>(d);
    aliveL &= (win.w[kWinHalf - d] > half) & (dv <= left_max);
    aliveR &= (win.w[kWinHalf + d] > half) & (dv <= right_max);
    left -= aliveL;
    right -= aliveR;
    if (!lanes::any(aliveL | aliveR)) break;
  }
}

// The batched fit's input for every lane from the window at imax - kHalf .. imax + kHalf - 1 (kHalf = the
// fit's kBatchHalf): y[x][lane] = (float(sample) - bg[lane]) * inv, the one-row fill's float arithmetic, in
// 4-float vectors (lanes whose fit window starts elsewhere are overwritten by the caller).
template <int kHalf>
inline void lane_fill_batch(const LaneWindow& win, const float* bg, float inv, float (*y)[kLaneRows]) {
  using F32 = float __attribute__((vector_size(16)));
  F32 b0, b1;
  std::memcpy(&b0, bg, sizeof b0);
  std::memcpy(&b1, bg + 4, sizeof b1);
  const F32 iv = F32{} + inv;
  for (int x = 0; x < 2 * kHalf; ++x) {
    const LaneI16 v = win.w[kWinHalf - kHalf + x];
    const F32 f0 = (__builtin_convertvector(lanes::widen32_lo(v), F32) - b0) * iv;
    const F32 f1 = (__builtin_convertvector(lanes::widen32_hi(v), F32) - b1) * iv;
    std::memcpy(y[x], &f0, sizeof f0);
    std::memcpy(y[x] + 4, &f1, sizeof f1);
  }
}

}  // namespace fs::fw::detail
