#include "host/recognize/convex_clip.hpp"

#include <cstdint>
#include <cstring>
#include <limits>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

namespace fs::host::rec {

namespace {

// GCC vector extensions (four lanes): AVX2 registers in clip_convex_avx2, SSE2 pairs in the portable variant
// on x86, NEON on arm. clip_convex_avx512 is written in intrinsics.
using V4 = double __attribute__((vector_size(32)));
using M4 = std::int64_t __attribute__((vector_size(32)));

// Always inlined: an out-of-line copy (at -O0) would be built for the baseline and return its bytes in
// memory, while the AVX variants expect them in a register.
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

// Constants of the kernels.
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kGrazing = 1e-9;
// A back face's exit and the entry are compared by a product beyond this relative margin (far above its
// rounding), by the division within it.
constexpr double kSure = 1e-12;

// The first face of the largest of n entries (per lane: entry and face), from 0 (no entry: -1).
__attribute__((always_inline)) inline std::int64_t largest_entry(const double* enter,
                                                                 const std::int64_t* face, std::size_t n,
                                                                 double& e) {
  e = 0.0;
  std::int64_t best = -1;
  for (std::size_t k = 0; k < n; ++k)
    if (enter[k] > e || (enter[k] == e && face[k] >= 0 && face[k] < best)) e = enter[k], best = face[k];
  return best;
}

// Whether a back face lets the ray out before e, face by face (the exact test where the product is unsure).
__attribute__((always_inline)) inline bool leaves_before(const ClipFaces::Columns& bk, double dx, double dy,
                                                         double dz, double e) {
  for (std::size_t i = 0; i < bk.h.size(); ++i) {
    const double den = bk.nx[i] * dx + bk.ny[i] * dy + bk.nz[i] * dz;
    if (den > kGrazing && e > -bk.h[i] / den) return true;
  }
  return false;
}

// The kernel, four faces at a time, inlined into each four-lane variant (compiled for that variant's
// instruction set).
__attribute__((always_inline)) inline int clip(const ClipFaces& faces, double dx, double dy, double dz,
                                               double& distance) {
  constexpr std::size_t N = kClipLanes;
  distance = kInf;
  const ClipFaces::Columns& fr = faces.front();
  const std::size_t nf = fr.h.size();
  if (nf == 0) return -1;  // the origin inside every face plane
  // Entries: every front face must be entered (a ray parallel to one, or leaving it, stays outside it).
  V4 enter = V4{} + 0.0;
  M4 face = M4{} - 1;  // per lane: the face of its largest entry (the first of equal ones)
  M4 not_entered = M4{};
  for (std::size_t i = 0; i < nf; i += N) {
    const V4 den = load(fr.nx.data() + i) * dx + load(fr.ny.data() + i) * dy + load(fr.nz.data() + i) * dz;
    not_entered |= ~(den < -kGrazing);
    const V4 s = -load(fr.h.data() + i) / den;
    const M4 later = s > enter;
    enter = later ? s : enter;
    face = later ? load_index(faces.front_index().data() + i) : face;
  }
  if (any(not_entered)) return -1;
  double lane_enter[N];
  std::int64_t lane_face[N];
  std::memcpy(lane_enter, &enter, sizeof enter);
  std::memcpy(lane_face, &face, sizeof face);
  double e = 0.0;
  const std::int64_t best = largest_entry(lane_enter, lane_face, N, e);
  if (best < 0) return -1;
  // Exits: a back face the ray leaves (den > 0) at -h / den before e is a miss.
  const ClipFaces::Columns& bk = faces.back();
  const std::size_t nb = bk.h.size();
  const V4 ev = V4{} + e;
  M4 before = M4{}, unsure = M4{};
  for (std::size_t i = 0; i < nb; i += N) {
    const V4 den = load(bk.nx.data() + i) * dx + load(bk.ny.data() + i) * dy + load(bk.nz.data() + i) * dz;
    const V4 y = -load(bk.h.data() + i);
    const V4 p = ev * den;
    const M4 leaves = den > kGrazing;
    const M4 early = p > y * (1.0 + kSure);
    before |= leaves & early;
    unsure |= leaves & ~early & ~(p < y * (1.0 - kSure));
  }
  if (any(before)) return -1;
  if (any(unsure) && leaves_before(bk, dx, dy, dz, e)) return -1;
  distance = e;
  return static_cast<int>(best);
}

}  // namespace

#if defined(__x86_64__)
namespace {

// -v, by its sign bit (as the four-lane kernel's negation).
__attribute__((target("avx512f"), always_inline)) inline __m512d neg8(__m512d v) {
  const __m512i sign = _mm512_set1_epi64(std::numeric_limits<std::int64_t>::min());
  return _mm512_castsi512_pd(_mm512_xor_si512(_mm512_castpd_si512(v), sign));
}

// Faces i..i+7 of c: n . (dx, dy, dz), summed in the four-lane kernel's order.
__attribute__((target("avx512f"), always_inline)) inline __m512d dot8(const ClipFaces::Columns& c,
                                                                      std::size_t i, __m512d vx, __m512d vy,
                                                                      __m512d vz) {
  return _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(_mm512_loadu_pd(c.nx.data() + i), vx),
                                     _mm512_mul_pd(_mm512_loadu_pd(c.ny.data() + i), vy)),
                       _mm512_mul_pd(_mm512_loadu_pd(c.nz.data() + i), vz));
}

}  // namespace

// The same kernel, eight faces at a time, in AVX-512 intrinsics (GCC's generic vectors of eight lanes turn
// the mask operations into scalar code). The same operations in the same order: the same results.
__attribute__((target("avx512f"))) int clip_convex_avx512(const ClipFaces& faces, double dx, double dy,
                                                          double dz, double& distance) {
  constexpr std::size_t N = kClipMaxLanes;
  distance = kInf;
  const ClipFaces::Columns& fr = faces.front();
  const std::size_t nf = fr.h.size();
  if (nf == 0) return -1;
  const __m512d vx = _mm512_set1_pd(dx), vy = _mm512_set1_pd(dy), vz = _mm512_set1_pd(dz);
  __m512d enter = _mm512_setzero_pd();
  __m512i face = _mm512_set1_epi64(-1);
  __mmask8 not_entered = 0;
  const __m512d minus_grazing = _mm512_set1_pd(-kGrazing);
  for (std::size_t i = 0; i < nf; i += N) {
    const __m512d den = dot8(fr, i, vx, vy, vz);
    not_entered |= static_cast<__mmask8>(~_mm512_cmp_pd_mask(den, minus_grazing, _CMP_LT_OQ));
    const __m512d s = _mm512_div_pd(neg8(_mm512_loadu_pd(fr.h.data() + i)), den);
    const __mmask8 later = _mm512_cmp_pd_mask(s, enter, _CMP_GT_OQ);
    enter = _mm512_mask_blend_pd(later, enter, s);
    face = _mm512_mask_blend_epi64(later, face, _mm512_loadu_si512(faces.front_index().data() + i));
  }
  if (not_entered != 0) return -1;
  double lane_enter[N];
  std::int64_t lane_face[N];
  _mm512_storeu_pd(lane_enter, enter);
  _mm512_storeu_si512(lane_face, face);
  double e = 0.0;
  const std::int64_t best = largest_entry(lane_enter, lane_face, N, e);
  if (best < 0) return -1;
  const ClipFaces::Columns& bk = faces.back();
  const std::size_t nb = bk.h.size();
  const __m512d ev = _mm512_set1_pd(e), grazing = _mm512_set1_pd(kGrazing);
  const __m512d above = _mm512_set1_pd(1.0 + kSure), below = _mm512_set1_pd(1.0 - kSure);
  __mmask8 before = 0, unsure = 0;
  for (std::size_t i = 0; i < nb; i += N) {
    const __m512d den = dot8(bk, i, vx, vy, vz);
    const __m512d y = neg8(_mm512_loadu_pd(bk.h.data() + i));
    const __m512d p = _mm512_mul_pd(ev, den);
    const __mmask8 leaves = _mm512_cmp_pd_mask(den, grazing, _CMP_GT_OQ);
    const __mmask8 early = _mm512_cmp_pd_mask(p, _mm512_mul_pd(y, above), _CMP_GT_OQ);
    const __mmask8 sure_before = _mm512_cmp_pd_mask(p, _mm512_mul_pd(y, below), _CMP_LT_OQ);
    before |= leaves & early;
    unsure |= static_cast<__mmask8>(leaves & ~early & ~sure_before);
  }
  if (before != 0) return -1;
  if (unsure != 0 && leaves_before(bk, dx, dy, dz, e)) return -1;
  distance = e;
  return static_cast<int>(best);
}
#endif

void ClipFaces::reserve(std::size_t n) {
  const std::size_t padded = n + kClipMaxLanes;
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

void ClipFaces::pad(std::size_t lanes) {
  while (front_.h.size() % lanes != 0) {
    front_.nx.push_back(front_.nx.front());
    front_.ny.push_back(front_.ny.front());
    front_.nz.push_back(front_.nz.front());
    front_.h.push_back(front_.h.front());
    front_index_.push_back(front_index_.front());
  }
  while (back_.h.size() % lanes != 0) {
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

namespace {

struct Cpu {  // detected once (thread-safe, no allocation)
  bool avx2 = false, avx512 = false;
  Cpu() {
    __builtin_cpu_init();
    avx2 = __builtin_cpu_supports("avx2") != 0;
    avx512 = __builtin_cpu_supports("avx512f") != 0;
  }
};

const Cpu& cpu() {
  static const Cpu c;
  return c;
}

}  // namespace

bool clip_convex_has_avx2() { return cpu().avx2; }
bool clip_convex_has_avx512() { return cpu().avx512; }
#else
bool clip_convex_has_avx2() { return false; }
bool clip_convex_has_avx512() { return false; }
#endif

std::size_t clip_lanes() { return clip_convex_has_avx512() ? kClipMaxLanes : kClipLanes; }

int clip_convex(const ClipFaces& faces, double dx, double dy, double dz, double& distance) {
#if defined(__x86_64__)
  if (clip_convex_has_avx512() && faces.front().h.size() % kClipMaxLanes == 0 &&
      faces.back().h.size() % kClipMaxLanes == 0)
    return clip_convex_avx512(faces, dx, dy, dz, distance);
  if (clip_convex_has_avx2()) return clip_convex_avx2(faces, dx, dy, dz, distance);
#endif
  return clip_convex_portable(faces, dx, dy, dz, distance);
}

}  // namespace fs::host::rec
