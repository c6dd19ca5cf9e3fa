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

__attribute__((always_inline)) inline M4 load_index(const std::int64_t* p) {
  M4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

// Masks are gathered over a loop and tested once after it: a lane test inside the loop costs more (the
// generic vectors have no movemask) than the divisions and branches it could save.
__attribute__((always_inline)) inline bool any(M4 m) { return (m[0] | m[1] | m[2] | m[3]) != 0; }

// The kernel, inlined into each variant (compiled for that variant's instruction set).
__attribute__((always_inline)) inline int clip(const ClipFaces& faces, double dx, double dy, double dz,
                                               double& distance) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  constexpr double kGrazing = 1e-9;
  // A back face's exit and the entry are compared by a product beyond this relative margin (far above its
  // rounding), by the division within it.
  constexpr double kSure = 1e-12;
  distance = kInf;
  const ClipFaces::Columns& fr = faces.front();
  const std::size_t nf = fr.h.size();
  if (nf == 0) return -1;  // the origin inside every face plane
  // Entries: every front face must be entered (a ray parallel to one, or leaving it, stays outside it).
  V4 enter = {0.0, 0.0, 0.0, 0.0};
  M4 face = {-1, -1, -1, -1};  // per lane: the face of its largest entry (the first of equal ones)
  M4 not_entered = {0, 0, 0, 0};
  for (std::size_t i = 0; i < nf; i += kClipLanes) {
    const V4 den = load(fr.nx.data() + i) * dx + load(fr.ny.data() + i) * dy + load(fr.nz.data() + i) * dz;
    not_entered |= ~(den < -kGrazing);
    const V4 s = -load(fr.h.data() + i) / den;
    const M4 later = s > enter;
    enter = later ? s : enter;
    face = later ? load_index(faces.front_index().data() + i) : face;
  }
  if (any(not_entered)) return -1;
  double e = 0.0;
  std::int64_t best = -1;
  for (std::size_t k = 0; k < kClipLanes; ++k)
    if (enter[k] > e || (enter[k] == e && face[k] >= 0 && face[k] < best)) e = enter[k], best = face[k];
  if (best < 0) return -1;
  // Exits: a back face the ray leaves (den > 0) at -h / den before e is a miss.
  const ClipFaces::Columns& bk = faces.back();
  const std::size_t nb = bk.h.size();
  const V4 ev = {e, e, e, e};
  M4 before = {0, 0, 0, 0}, unsure = {0, 0, 0, 0};
  for (std::size_t i = 0; i < nb; i += kClipLanes) {
    const V4 den = load(bk.nx.data() + i) * dx + load(bk.ny.data() + i) * dy + load(bk.nz.data() + i) * dz;
    const V4 y = -load(bk.h.data() + i);
    const V4 p = ev * den;
    const M4 leaves = den > kGrazing;
    const M4 early = p > y * (1.0 + kSure);
    before |= leaves & early;
    unsure |= leaves & ~early & ~(p < y * (1.0 - kSure));
  }
  if (any(before)) return -1;
  if (any(unsure))
    for (std::size_t i = 0; i < nb; ++i) {
      const double den = bk.nx[i] * dx + bk.ny[i] * dy + bk.nz[i] * dz;
      if (den > kGrazing && e > -bk.h[i] / den) return -1;
    }
  distance = e;
  return static_cast<int>(best);
}

}  // namespace

void ClipFaces::reserve(std::size_t n) {
  const std::size_t padded = n + kClipLanes;
  for (Columns* c : {&front_, &back_}) {
    c->nx.reserve(padded);
    c->ny.reserve(padded);
    c->nz.reserve(padded);
    c->h.reserve(padded);
  }
  front_index_.reserve(padded);
}

void ClipFaces::clear() {
  for (Columns* c : {&front_, &back_}) {
    c->nx.clear();
    c->ny.clear();
    c->nz.clear();
    c->h.clear();
  }
  front_index_.clear();
}

void ClipFaces::add(double nx, double ny, double nz, double h, int index) {
  Columns& c = h > 0.0 ? front_ : back_;
  c.nx.push_back(nx);
  c.ny.push_back(ny);
  c.nz.push_back(nz);
  c.h.push_back(h);
  if (h > 0.0) front_index_.push_back(index);
}

void ClipFaces::pad() {
  while (front_.h.size() % kClipLanes != 0) {
    front_.nx.push_back(front_.nx.front());
    front_.ny.push_back(front_.ny.front());
    front_.nz.push_back(front_.nz.front());
    front_.h.push_back(front_.h.front());
    front_index_.push_back(front_index_.front());
  }
  while (back_.h.size() % kClipLanes != 0) {
    back_.nx.push_back(0.0);
    back_.ny.push_back(0.0);
    back_.nz.push_back(0.0);
    back_.h.push_back(-1.0);
  }
}

int clip_convex_portable(const ClipFaces& faces, double dx, double dy, double dz, double& distance) {
  return clip(faces, dx, dy, dz, distance);
}

#if defined(__x86_64__)
__attribute__((target("avx2"))) int clip_convex_avx2(const ClipFaces& faces, double dx, double dy, double dz,
                                                     double& distance) {
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

int clip_convex(const ClipFaces& faces, double dx, double dy, double dz, double& distance) {
#if defined(__x86_64__)
  if (clip_convex_has_avx2()) return clip_convex_avx2(faces, dx, dy, dz, distance);
#endif
  return clip_convex_portable(faces, dx, dy, dz, distance);
}

}  // namespace fs::host::rec
