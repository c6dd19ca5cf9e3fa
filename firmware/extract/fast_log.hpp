#pragma once
// Logarithm and exponential for the sub-pixel fits, from the IEEE bits plus a short series: plain arithmetic
// (no libm, no table), branch-free, so loops over them vectorize, and the same result on every target.
//   fast_ln (double): absolute error < 1e-9 for every positive normal double.
//   fast_lnf (float): absolute error < 2e-7 for every positive normal float.
//   fast_expf (float): relative error < 3e-7 on [-80, 80]; the argument must lie in that range (no clamp: a
//   float select there would keep the vectorizer off the caller's loop under -ftrapping-math).
// All tested against libm in tests/firmware/extract_scan_test.cpp.
#include <bit>
#include <cstdint>

namespace fs::fw::detail {

inline double fast_ln(double x) {  // x > 0 and normal
  const std::uint64_t bits = std::bit_cast<std::uint64_t>(x);
  std::int64_t e = static_cast<std::int64_t>((bits >> 52) & 0x7ff) - 1023;
  double m = std::bit_cast<double>((bits & 0x000fffffffffffffULL) | 0x3ff0000000000000ULL);  // [1, 2)
  if (m > 1.4142135623730951) {  // -> [0.707, 1.414): |t| <= 0.1716
    m *= 0.5;
    ++e;
  }
  const double t = (m - 1.0) / (m + 1.0), t2 = t * t;
  // ln m = 2 atanh t = 2 (t + t^3/3 + t^5/5 + ...); the first omitted term is 2 t^13 / 13 < 2e-11.
  const double series =
      1.0 + t2 * (1.0 / 3 + t2 * (1.0 / 5 + t2 * (1.0 / 7 + t2 * (1.0 / 9 + t2 * (1.0 / 11)))));
  return static_cast<double>(e) * 0.69314718055994531 + 2.0 * t * series;
}

inline float fast_lnf(float x) {  // x > 0 and normal
  const std::uint32_t bits = std::bit_cast<std::uint32_t>(x);
  // Mantissa in [1, 2), or [0.5, 1) with the exponent + 1 when it exceeds sqrt(2): m in [0.707, 1.414).
  // Decided on the bits with integer selects only (a float compare or select may trap under the default
  // -ftrapping-math, which keeps the vectorizer off the loop).
  const std::uint32_t big = (bits & 0x007fffffU) > 0x003504f3U ? 1U : 0U;
  const float m = std::bit_cast<float>((bits & 0x007fffffU) | (0x3f800000U - (big << 23)));
  const float e = static_cast<float>(static_cast<std::int32_t>((bits >> 23) + big) - 127);
  const float t = (m - 1.0f) / (m + 1.0f), t2 = t * t;
  const float series = 1.0f + t2 * (1.0f / 3 + t2 * (1.0f / 5 + t2 * (1.0f / 7 + t2 * (1.0f / 9))));
  return e * 0.693147181f + 2.0f * t * series;
}

inline float fast_expf(float z) {
  // z = k ln2 + r, |r| <= ln2 / 2; k by the round-to-nearest magic constant (1.5 * 2^23).
  const float kf = (z * 1.44269504f + 12582912.0f) - 12582912.0f;
  const float r = (z - kf * 0.693145752f) - kf * 1.42860677e-6f;  // ln2 split in two for accuracy
  const float p =
      1.0f + r * (1.0f + r * (0.5f + r * (1.0f / 6 + r * (1.0f / 24 + r * (1.0f / 120 + r * (1.0f / 720))))));
  const std::int32_t k = static_cast<std::int32_t>(kf);
  return p * std::bit_cast<float>(static_cast<std::uint32_t>(k + 127) << 23);
}

// The same two on 4 or 8 floats at once, as GCC/Clang generic vectors (vector_size: SSE2/AVX2 on x86-64, NEON
// on arm, plain scalar code where a target has no SIMD): the identical operation sequence lane by lane, so
// each lane equals the scalar function bit for bit (tested).
using f32x4 = float __attribute__((vector_size(16)));
using i32x4 = std::int32_t __attribute__((vector_size(16)));
using u32x4 = std::uint32_t __attribute__((vector_size(16)));
using f32x8 = float __attribute__((vector_size(32)));
using i32x8 = std::int32_t __attribute__((vector_size(32)));
using u32x8 = std::uint32_t __attribute__((vector_size(32)));

template <typename F, typename I, typename U>
inline F fast_lnf_v(F x) {
  const U bits = std::bit_cast<U>(x);
  const U big = std::bit_cast<U>((bits & 0x007fffffU) > 0x003504f3U) & 1U;  // compare: 0 / -1
  const F m = std::bit_cast<F>((bits & 0x007fffffU) | (0x3f800000U - (big << 23)));
  const F e = __builtin_convertvector(std::bit_cast<I>((bits >> 23) + big) - 127, F);
  const F t = (m - 1.0f) / (m + 1.0f), t2 = t * t;
  const F series = 1.0f + t2 * (1.0f / 3 + t2 * (1.0f / 5 + t2 * (1.0f / 7 + t2 * (1.0f / 9))));
  return e * 0.693147181f + 2.0f * t * series;
}

template <typename F, typename I, typename U>
inline F fast_expf_v(F z) {
  const F kf = (z * 1.44269504f + 12582912.0f) - 12582912.0f;
  const F r = (z - kf * 0.693145752f) - kf * 1.42860677e-6f;
  const F p =
      1.0f + r * (1.0f + r * (0.5f + r * (1.0f / 6 + r * (1.0f / 24 + r * (1.0f / 120 + r * (1.0f / 720))))));
  const I k = __builtin_convertvector(kf, I);
  return p * std::bit_cast<F>(std::bit_cast<U>(k + 127) << 23);
}

inline f32x4 fast_lnf(f32x4 x) { return fast_lnf_v<f32x4, i32x4, u32x4>(x); }
inline f32x8 fast_lnf(f32x8 x) { return fast_lnf_v<f32x8, i32x8, u32x8>(x); }
inline f32x4 fast_expf(f32x4 z) { return fast_expf_v<f32x4, i32x4, u32x4>(z); }
inline f32x8 fast_expf(f32x8 z) { return fast_expf_v<f32x8, i32x8, u32x8>(z); }

}  // namespace fs::fw::detail
