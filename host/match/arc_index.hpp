#pragma once
// A library index exact with respect to the inexact matcher's pruning conditions (thesis table 7.6).
//
// Every search solution of two or more faces passes through a level-2 state: a scene arc (s0, s1) between two
// real faces matched to a reference arc (r0, r1) (1 connectivity, 7 neighbour match), whose pairs pass
//   - 3 rigidity from the level-1 parent (MatchParams::rigidity_pairs):
//     |angle(n_r0, n_r1) - angle(n_s0, n_s1)| <= TH_omega, and
//   - the one-sided area part of 9.1: area_s <= th_area_ratio * area_r + th_area_slack_mm2, for both pairs,
//     area_r counted with the neighbours across folds of up to th_area_fold_deg. The index's areas count
//     those of up to kAreaFoldMaxDeg, at least as many; a larger th_area_fold_deg switches its area part off.
// ArcIndex holds every reference arc in both directions, bucketed by the angle between its normals (a 90 deg
// arc of a box and one of a wedge meet the same bucket) and sorted by area; candidates() marks the references
// that hold such an arc for some arc of a scene graph. A reference it leaves unmarked cannot produce a
// solution under the same parameters (TH_minlevel >= 2), so matching only the marked ones changes no result.
// Conditions that are switched off are not used; when connectivity or neighbour match is off, or TH_minlevel
// < 2, every reference is a candidate.
//
// With TH_minlevel >= 3 a solution also passes through a level-3 state: a third pair (z, t) whose faces
// border one of the first two, x or y, in both graphs, and whose reference normal the rotation fit of the
// first two pairs turns within TH_omega of the scene normal (3 rigidity). That fit turns n_x and n_y within
// e_x, e_y of their scene normals, e_x + e_y = delta = the first pair's angle difference (<= TH_omega): the
// optimum lies between aligning one pair exactly (the other then off by delta) and the other. A rotation
// keeps angles, so |angle(n_z, n_x) - angle(n_t, n_s_x)| <= TH_omega + delta, the same for y. The index keeps
// each reference's paths of two arcs (x - y - z) by their three angles (with the largest face areas of the
// paths sharing them) and drops a reference when no path of the part passes that way. A reference with two
// adjacent faces within MatchParams::degenerate_deg of parallel is not checked by paths (such a first pair
// has no rotation fit).
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "host/match/params.hpp"
#include "host/pfrg/pfrg.hpp"

namespace fs::host::match {

class ArcIndex {
 public:
  struct Entry {
    float angle;   // degrees between the two faces' normals, [0, 180]
    float a0, a1;  // areas of the arc's first and second face, with their shallow folds (mm^2)
    std::uint32_t ref;
  };
  struct PathSig {
    float xy, yz, xz;  // angles between the normals of x - y - z (degrees)
    float ax, ay, az;  // the largest areas (as Entry's) of the reference's paths with these angles
  };

  ArcIndex() = default;
  explicit ArcIndex(std::span<const Pfrg* const> references);
  // The index of several libraries one after the other (reference k of parts[1] becomes
  // parts[0]->references() + k): the same candidates as an index built over all their references.
  static ArcIndex concat(std::span<const ArcIndex* const> parts);

  // Its arrays, as a library file stores them (.fslib), and an index made of them again: from_arrays checks
  // sizes, ranges and order (what candidates() relies on) and throws fs::Error saying what is wrong.
  std::span<const Entry> entry_array() const { return entries_; }
  std::span<const PathSig> path_array() const { return paths_; }
  std::span<const std::uint32_t> path_starts() const { return path_start_; }
  std::span<const float> flattest_array() const { return flattest_; }
  std::span<const std::uint32_t> fingerprints() const { return fingerprints_; }
  static ArcIndex from_arrays(std::size_t references, std::vector<Entry> entries, std::vector<PathSig> paths,
                              std::vector<std::uint32_t> path_start, std::vector<float> flattest,
                              std::vector<std::uint32_t> fingerprints);
  // True when reference k of the index was built from a graph with the same fingerprint (a hash of its real
  // faces' ids, areas and normals and its arcs between them), for every k: a stored index that no longer
  // describes its library's models is not used. A change to how the index is built must change
  // kFslibVersion (host/library/library.hpp), so that stored indexes of the old kind are not read.
  bool describes(std::span<const Pfrg* const> references) const;
  static std::uint32_t fingerprint(const Pfrg& g);

  std::size_t references() const { return references_; }
  std::size_t entries() const { return entries_.size(); }  // directed reference arcs kept
  std::size_t bytes() const {
    return entries_.capacity() * sizeof(Entry) + paths_.capacity() * sizeof(PathSig) +
           (path_start_.capacity() + fingerprints_.capacity()) * sizeof(std::uint32_t) +
           flattest_.capacity() * sizeof(float);
  }

  // The index applies to matches under p (else every reference is a candidate).
  static bool applies(const MatchParams& p);
  // Working memory of candidates() (sized once; a part with more paths than it holds is checked by arcs
  // only).
  struct Scratch {
    Scratch();
    std::vector<int> adj_start, adj, cursor;  // by node index: neighbouring real faces
    struct Path {
      float xy, yz, xz;              // angles between the faces' normals (degrees)
      float need_x, need_y, need_z;  // smallest reference areas (one-sided area condition)
    };
    std::vector<Path> paths;
  };
  // mark[k] |= bit for every reference k that may hold a solution of `scene` under p (all of them when the
  // index does not apply). mark must have references() entries. No allocation.
  void candidates(const Pfrg& scene, const MatchParams& p, std::span<std::uint64_t> mark, std::uint64_t bit,
                  Scratch& scratch) const;

 private:
  static constexpr int kBuckets = 181;  // 1 degree each
  std::size_t references_ = 0;
  std::vector<Entry> entries_;  // by bucket, a0 descending within one
  std::array<std::uint32_t, kBuckets + 1> start_{};
  std::vector<PathSig> paths_;                // by reference
  std::vector<std::uint32_t> path_start_{0};  // reference k: paths_[path_start_[k], path_start_[k + 1])
  // Reference k: its arc closest to parallel faces (min(angle, 180 - angle)); a level-2 state below the
  // degenerate angle has no rotation fit, so such a reference is not checked by paths.
  std::vector<float> flattest_;
  std::vector<std::uint32_t> fingerprints_;  // reference k: fingerprint(its graph)
  void add_reference(const Pfrg& g, std::uint32_t ref);
  void sort_entries();   // entries_ by bucket, then a0 descending; then count_buckets()
  void count_buckets();  // start_ from entries_
  bool path_passes(const Scratch& scratch, std::size_t ref, double omega) const;
};

}  // namespace fs::host::match
