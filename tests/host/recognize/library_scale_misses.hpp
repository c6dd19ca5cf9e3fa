#pragma once
// bench_library_scale's account of a scan: why a true object was missed (--verbose), whether the view's edge
// cuts it, which scene regions join several of its faces, and how many other models fit its view as well
// (--lookalikes).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <unordered_map>
#include <vector>

#include "host/library/library.hpp"
#include "host/match/inexact.hpp"
#include "host/recognize/hypotheses.hpp"
#include "host/recognize/pose.hpp"
#include "host/recognize/recognizer.hpp"
#include "host/recognize/verify.hpp"
#include "library_scale_scenes.hpp"

namespace fs::bench {

// The verification's fine sample set of a scene's cloud.
inline host::rec::SampleSet fine_samples(const BenchScene& sc, const host::rec::VerifyParams& vp) {
  namespace rec = host::rec;
  rec::SampleSet samples;
  samples.build(sc.cloud,
                rec::sample_steps(rec::grid_spacing_mm(sc.cloud), vp.sample_step, vp.sample_spacing_mm));
  return samples;
}

// --lookalikes: how many other models fit the view of true object o as well as its own model does. The last
// matching round's hypotheses (those that survived the merge) nearer o than any other true object are checked
// on the fine samples without refinement, as the truth in its true pose; a model fits as well when one of its
// hypotheses rests on the table (its lowest point within 1 mm of it, as the true object's) and has at least
// the truth's inliers and at most its violations, within 2 sample points. The count is a lower bound: models
// without such a hypothesis there are not seen.
inline int count_lookalikes(const BenchScene& sc, const TrueObject& o, int truth, const host::Library& lib,
                            const host::rec::Recognizer& recognizer) {
  namespace rec = host::rec;
  const rec::VerifyParams vp;
  const rec::SampleSet samples = fine_samples(sc, vp);
  rec::Verifier verifier(vp);
  const host::Model& tm = lib.models[static_cast<std::size_t>(truth)];
  Mat3 R = o.R;
  Vec3 t = o.t;
  const rec::VerifyResult vt = verifier.verify(samples, rec::ModelGeometry(tm), R, t, false);
  constexpr int slack = 2;
  const Vec3 centre = o.R * tm.center + o.t;
  // The other true objects' centres: a hypothesis nearer one of them stands for that object.
  std::vector<Vec3> others;
  for (const TrueObject& other : sc.objects) {
    if (other.model.empty() || &other == &o) continue;
    for (const host::Model& m : lib.models)
      if (m.name == other.model) others.push_back(other.R * m.center + other.t);
  }
  std::unordered_map<int, std::unique_ptr<rec::ModelGeometry>> geometry;
  std::unordered_map<int, bool> fits;
  for (const rec::Hypothesis* h : recognizer.all_hypotheses()) {
    if (h->model == truth || fits[h->model]) continue;
    const auto& model = lib.models[static_cast<std::size_t>(h->model)];
    const Vec3 c = h->R * model.center + h->t;
    if (std::any_of(others.begin(), others.end(),
                    [&](const Vec3& x) { return (x - c).norm() < (centre - c).norm(); }))
      continue;
    // A placement that floats or sinks into the table is no look-alike: the true object rests on it.
    if (std::abs(rec::lowest_point(model, h->R, h->t, sc.table, nullptr)) > 1.0) continue;
    auto& g = geometry[h->model];
    if (!g) g = std::make_unique<rec::ModelGeometry>(model);
    R = h->R;
    t = h->t;
    const rec::VerifyResult v = verifier.verify(samples, *g, R, t, false);
    fits[h->model] = v.inliers >= vt.inliers - slack && v.violations <= vt.violations + slack;
  }
  int n = 0;
  for (const auto& [m, f] : fits) n += f ? 1 : 0;
  return n;
}

// Cells on the grid's border that lie on true object o (above the table, within its bounding sphere): the
// view's edge cuts it.
inline int cells_on_the_edge(const BenchScene& sc, const TrueObject& o, const host::Model& tm) {
  const Vec3 centre = o.R * tm.center + o.t;
  int edge = 0;
  auto count = [&](std::uint32_t r, std::uint32_t c) {
    const Vec3 p = sc.cloud.at(r, c).cast<double>();
    if (std::isfinite(p.x()) && sc.table.signed_distance(p) > 1.0 &&
        (p - centre).norm() < tm.bounding_radius + 1.0)
      ++edge;
  };
  if (sc.cloud.width < 2 || sc.cloud.height < 2) return 0;
  for (std::uint32_t c = 0; c < sc.cloud.width; ++c) count(0, c), count(sc.cloud.height - 1, c);
  for (std::uint32_t r = 1; r + 1 < sc.cloud.height; ++r) count(r, 0), count(r, sc.cloud.width - 1);
  return edge;
}

// Scene regions that hold points of several of the true model's faces, 100 cells or more of each (said when
// they are coplanar: faces the view joins into one region, where the matcher pairs a scene face with one
// model face). The scene node id is the region's label + 1.
inline void print_merged_faces(const BenchScene& sc, const TrueObject& o, const host::Model& tm,
                               const host::seg::Segmentation& seg) {
  constexpr int kMinCells = 100;
  if (seg.labels.size() != sc.cloud.points.size()) return;
  std::map<std::int32_t, std::map<std::size_t, int>> per_region;
  for (std::size_t cell = 0; cell < seg.labels.size(); ++cell) {
    const std::int32_t r = seg.labels[cell];
    if (r < 0) continue;
    const Vec3 p = o.R.transpose() * (sc.cloud.points[cell].cast<double>() - o.t);
    for (std::size_t f = 0; f < tm.faces.size(); ++f) {
      const auto& mf = tm.faces[f];
      if (std::abs(mf.normal.dot(p) - mf.offset) < 0.5 && inside_face(mf, p)) {
        ++per_region[r][f];
        break;
      }
    }
  }
  for (const auto& [r, faces] : per_region) {
    // The faces of this region with enough cells, and whether they all lie on one plane.
    int big = 0, first = -1;
    bool coplanar = true;
    for (const auto& [f, n] : faces) {
      if (n < kMinCells) continue;
      ++big;
      if (first < 0) {
        first = static_cast<int>(f);
        continue;
      }
      const auto& a = tm.faces[static_cast<std::size_t>(first)];
      coplanar = coplanar && a.normal.dot(tm.faces[f].normal) > 0.9999 &&
                 std::abs(a.offset - tm.faces[f].offset) < 0.5;
    }
    if (big < 2) continue;
    std::printf("    scene node %d joins %d %sfaces of the true model:", r + 1, big,
                coplanar ? "coplanar " : "");
    for (const auto& [f, n] : faces)
      if (n >= kMinCells) std::printf(" %zu (%d cells)", f, n);
    std::printf("\n");
  }
}

// A miss explained (--verbose): the verification of the true model in its true pose against that of the
// object reported there, on the same samples (no refinement): more inliers or fewer violations for the truth
// mean the search or the selection lost it, equal counts that the view cannot tell them apart. Then the true
// model searched alone (the first round's matching parameters, 64 solutions kept): at which rank its true
// placement comes, among all solutions and among those that pass the placement check. edge_cells:
// cells_on_the_edge of the object.
inline void why_missed(const BenchScene& sc, const TrueObject& o, const host::Model& tm,
                       const host::rec::Hypothesis* reported, const host::Library& lib,
                       const host::rec::Recognizer& recognizer, int edge_cells) {
  namespace rec = host::rec;
  const rec::VerifyParams vp;
  const rec::SampleSet samples = fine_samples(sc, vp);
  rec::Verifier verifier(vp);
  auto line = [&](const char* what, const host::Model& m, Mat3 R, Vec3 t) {
    const rec::ModelGeometry g(m);
    const rec::VerifyResult v = verifier.verify(samples, g, R, t, false);
    std::printf("    %s %s: inliers %d, violations %d, occluded %d, confidence %.3f\n", what, m.name.c_str(),
                v.inliers, v.violations, v.occluded, v.confidence);
  };
  line("truth", tm, o.R, o.t);
  if (edge_cells > 0)
    std::printf("    the view's edge cuts the object (%d border cells on it)\n", edge_cells);
  print_merged_faces(sc, o, tm, recognizer.segmentation());
  if (reported)
    line("reported", lib.models[static_cast<std::size_t>(reported->model)], reported->R, reported->t);
  const host::match::MatchParams mp = rec::match_params(recognizer.params());
  host::match::InexactMatcher matcher(host::match::MatcherLimits{200000, 64});
  const host::Pfrg& sg = recognizer.scene_graph();
  const auto& r = matcher.match(sg, tm.graph, mp);
  int placeable = 0, truth_rank = 0, truth_placeable_rank = 0;
  std::vector<rec::PlanePair> pairs;
  for (const auto& sol : r.solutions) {
    pairs.clear();
    for (const auto& nm : sol.matches)
      if (const auto* n = sg.find(nm.scene); n && n->has_plane) pairs.push_back(rec::plane_pair(*n, nm.ref));
    const bool ok = rec::consistent_placement(tm, sol.rotation, pairs, recognizer.params().placement);
    placeable += ok ? 1 : 0;
    // The true correspondence: the true rotation, and in the true pose every matched scene face on its plane
    // and its model face.
    bool truth = rec::rotation_angle_deg(sol.rotation, o.R) < 2.0;
    for (const auto& pp : pairs) {
      const auto& f = tm.faces[static_cast<std::size_t>(pp.model_face)];
      truth = truth && std::abs(pp.scene_normal.dot(o.t) - (pp.scene_offset - f.offset)) < 3.0 &&
              rec::outside_face_mm(f, o.R.transpose() * (pp.scene_centroid - o.t)) < 5.0;
    }
    if (truth && truth_rank == 0) truth_rank = sol.rank, truth_placeable_rank = ok ? placeable : -1;
  }
  std::printf(
      "    the true model searched alone: %zu solutions (%d placeable), the true placement at rank %d "
      "(%d among the placeable; 0 = none, -1 = not placeable)\n",
      r.solutions.size(), placeable, truth_rank, truth_placeable_rank);
}

}  // namespace fs::bench
