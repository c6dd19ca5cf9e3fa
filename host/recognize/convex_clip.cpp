#include "host/recognize/convex_clip.hpp"

#include <cstdint>
#include <cstring>
#include <limits>

namespace fs::host::rec {

namespace {

// GCC vector extensions: AVX2 registers in clip_convex_avx2, SSE2 pairs in the portable variant on x86,
// NEON on arm.
using V4 = double __attribute__((vector_size(32)));
using M4 = std::int64_t __attribute__((vector_size(32)));

// Always inlined: an out-of-line copy (at -O0) would be built for the baseline and return its 32 bytes in
// memory, while the AVX2 variant expects them in a register.
__attribute__((always_inline)) inline V4 load(const double* p) {
  V4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

// The kernel, inlined into each variant (compiled for that variant's instruction set).
__attribute__((always_inline)) inline int clip(const ConvexFaces& faces, double dx, double dy, double dz,
                                               double& distance) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  constexpr double kGrazing = 1e-9;
  V4 enter = {0.0, 0.0, 0.0, 0.0};
  V4 leave = {kInf, kInf, kInf, kInf};
  M4 grazing_outside = {0, 0, 0, 0};
  M4 face = {-1, -1, -1, -1};  // per lane: the face of its largest entry (the first of equal ones)
  M4 index = {0, 1, 2, 3};
  const M4 step = {4, 4, 4, 4};
  for (std::size_t i = 0; i < faces.count; i += kClipLanes, index += step) {
    const V4 h = load(faces.h + i);
    const V4 den = load(faces.nx + i) * dx + load(faces.ny + i) * dy + load(faces.nz + i) * dz;
    const V4 s = -h / den;
    const M4 enters = den < -kGrazing;
    const M4 leaves = den > kGrazing;
    grazing_outside |= ~(enters | leaves) & (h > 0.0);
    const M4 later = enters & (s > enter);
    enter = later ? s : enter;
    face = later ? index : face;
    leave = (leaves & (s < leave)) ? s : leave;
  }
  distance = kInf;
  double e = 0.0, l = kInf;
  std::int64_t best = -1;
  for (std::size_t k = 0; k < kClipLanes; ++k) {
    if (grazing_outside[k] != 0) return -1;
    if (enter[k] > e || (enter[k] == e && face[k] >= 0 && face[k] < best)) e = enter[k], best = face[k];
    if (leave[k] < l) l = leave[k];
  }
  if (best < 0 || e > l) return -1;
  distance = e;
  return static_cast<int>(best);
}

}  // namespace

int clip_convex_portable(const ConvexFaces& faces, double dx, double dy, double dz, double& distance) {
  return clip(faces, dx, dy, dz, distance);
}

#if defined(__x86_64__)
__attribute__((target("avx2"))) int clip_convex_avx2(const ConvexFaces& faces, double dx, double dy,
                                                     double dz, double& distance) {
  return clip(faces, dx, dy, dz, distance);
}

bool clip_convex_has_avx2() {
  static const bool detected = [] {  // once (thread-safe, no allocation)
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return detected;
}
#else
bool clip_convex_has_avx2() { return false; }
#endif

int clip_convex(const ConvexFaces& faces, double dx, double dy, double dz, double& distance) {
#if defined(__x86_64__)
  if (clip_convex_has_avx2()) return clip_convex_avx2(faces, dx, dy, dz, distance);
#endif
  return clip_convex_portable(faces, dx, dy, dz, distance);
}

}  // namespace fs::host::rec
