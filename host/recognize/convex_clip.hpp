// The ray clip of verification's hot loop (ModelGeometry::cast_convex): a ray against every face half-space
// of a convex model, four faces at a time. The faces are split by the rays' common origin: a ray can enter
// only through a front face (the origin outside its plane) and leave only through a back face, so only the
// front faces need a division; a back face only has to let the ray out no earlier than it entered.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace fs::host::rec {

// The faces a variant clips at a time: four (SSE2 pairs, AVX2, NEON) or, with AVX-512, eight.
inline constexpr std::size_t kClipLanes = 4;
inline constexpr std::size_t kClipMaxLanes = 8;

// The lanes of the variant clip_convex picks on this CPU: each half of ClipFaces is padded to a multiple.
std::size_t clip_lanes();

// One origin's faces as padded columns (structure of arrays). Front padding repeats the first front face (the
// same entry, the same index); back padding has a zero normal, which lets no ray out. No allocation once
// reserved.
class ClipFaces {
 public:
  void reserve(std::size_t faces);
  void clear();
  // Face `index` with unit normal n and height h = n . origin - offset (positive: the origin is outside its
  // plane, a front face). Faces are added in index order; pad() after the last.
  void add(double nx, double ny, double nz, double h, int index);
  void pad(std::size_t lanes = clip_lanes());

  struct Columns {
    std::vector<double> nx, ny, nz, h;
  };
  const Columns& front() const { return front_; }
  const Columns& back() const { return back_; }
  const std::vector<std::int64_t>& front_index() const { return front_index_; }

 private:
  Columns front_, back_;
  std::vector<std::int64_t> front_index_;
};

// The ray origin + s dir (s > 0) enters the model through the face of the latest entry and hits it when no
// face lets it out before. Returns that face (distance: its s), or -1 for a miss (distance: infinity): the
// ray parallel to a front face plane or pointing away from it, leaving before it enters, or entering nowhere
// ahead (the origin inside). Bit for bit the result of the face-by-face loop over all faces: the same
// divisions for the entries, the first face of the largest entry; a back face's exit is compared with the
// entry by a product and divided only when the two lie within 1e-12 of each other.
int clip_convex(const ClipFaces& faces, double dx, double dy, double dz, double& distance);

// The variants clip_convex picks from (the same results; tests run each the CPU has). The four-lane ones
// take columns padded to a multiple of 4, clip_convex_avx512 a multiple of 8; clip_convex falls back to four
// lanes for columns padded to 4 only.
int clip_convex_portable(const ClipFaces& faces, double dx, double dy, double dz, double& distance);
bool clip_convex_has_avx2();
bool clip_convex_has_avx512();
#if defined(__x86_64__)
int clip_convex_avx2(const ClipFaces& faces, double dx, double dy, double dz, double& distance);
int clip_convex_avx512(const ClipFaces& faces, double dx, double dy, double dz, double& distance);
#endif

}  // namespace fs::host::rec
