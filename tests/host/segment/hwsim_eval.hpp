#pragma once
// Evaluation of the segmentation and scene PFRG against hw-sim ground truth (used by the tests and by
// segment_report): Hoover classes of the faces that matter (> min_share of their object's visible area),
// normal errors, and the PFRG checked against the true visible faces and their adjacencies.
#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "host/segment/quality.hpp"
#include "host/segment/scene_pfrg.hpp"
#include "host/segment/segmenter.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/scene.hpp"

namespace fs::test {

struct HwsimEval {
  fs::host::OrganizedCloud cloud;
  fs::host::seg::Segmentation seg;
  fs::host::Pfrg graph;
  fs::host::seg::PreprocessStats stats;
  fs::host::seg::HooverResult hoover;
  std::map<std::int32_t, double> face_area;    // gt label -> visible area (mm^2)
  std::map<std::int32_t, double> object_area;  // object -> visible area
  std::set<std::int32_t> significant;          // gt labels above min_share of their object
  int significant_correct = 0;
  double max_normal_error_deg = 0.0;            // over the significant faces detected correctly
  std::set<std::pair<int, int>> expected_arcs;  // PFRG node ids (via the correct detections), no supernode
  std::set<std::pair<int, int>> actual_arcs;    // PFRG arcs between known nodes
  std::vector<std::string> problems;
};

// steps > 0 resamples the scene's sweep to that many galvo steps (same first and last mirror angle).
inline HwsimEval evaluate_hwsim_scene(
    const std::filesystem::path& scene_file, double noise_mm, double min_share = 0.02, std::uint64_t seed = 7,
    std::uint32_t steps = 0,
    const fs::host::seg::SegmentParams& params = fs::host::seg::SegmentParams::laser()) {
  HwsimEval ev;
  fs::sim::Scene scene = fs::sim::load_scene(scene_file);
  if (steps > 0) fs::sim::resample_sweep(scene.calibration, steps);
  const auto gt = fs::sim::make_ground_truth_grid(scene, {.depth_noise_mm = noise_mm, .seed = seed});
  gt.export_to(ev.cloud, true);
  fs::host::seg::SegmentLimits lim;
  lim.max_cells = ev.cloud.points.size();
  fs::host::seg::Segmenter segmenter(params, lim);
  segmenter.segment(ev.cloud, ev.seg);
  fs::host::seg::ScenePfrgBuilder builder(lim.max_regions, lim.max_borders);
  builder.build(ev.seg, ev.graph, &ev.stats);

  // true normals and visible areas per gt label (area from the true points of the grid cells)
  std::map<std::int32_t, Vec3> normal;
  const std::uint32_t w = ev.cloud.width, h = ev.cloud.height;
  for (std::uint32_t r = 0; r + 1 < h; ++r) {
    for (std::uint32_t k = 0; k + 1 < w; ++k) {
      const auto& c = gt.at(k, r);
      if (!c.valid()) continue;
      normal[c.label()] = c.normal;
      const auto& cu = gt.at(k + 1, r);
      const auto& cv = gt.at(k, r + 1);
      if (cu.label() != c.label() || cv.label() != c.label()) continue;
      const double a = (cu.true_point - c.true_point).cross(cv.true_point - c.true_point).norm();
      ev.face_area[c.label()] += a;
      ev.object_area[c.object] += a;
    }
  }
  ev.hoover =
      fs::host::seg::hoover_compare(ev.cloud.labels, ev.seg, 0.8, [&](std::int32_t l) -> std::optional<Vec3> {
        auto it = normal.find(l);
        if (it == normal.end()) return std::nullopt;
        return it->second;
      });
  for (const auto& [l, a] : ev.face_area) {
    const std::int32_t obj = l < 0 ? -1 : l / 1000;
    if (a > min_share * ev.object_area[obj]) ev.significant.insert(l);
  }
  for (auto l : ev.significant) {
    auto it = ev.hoover.gt_correct_region.find(l);
    if (it == ev.hoover.gt_correct_region.end()) {
      ev.problems.push_back("face " + std::to_string(l) + " (" + std::to_string(int(ev.face_area[l])) +
                            " mm^2) is " +
                            to_string(ev.hoover.gt_class.count(l) ? ev.hoover.gt_class.at(l)
                                                                  : fs::host::seg::HooverClass::Missed));
      continue;
    }
    ++ev.significant_correct;
    const Vec3 n = ev.seg.regions[std::size_t(it->second)].plane.n;
    const double err = std::acos(std::min(1.0, std::abs(n.dot(normal[l].normalized())))) * 180.0 / M_PI;
    ev.max_normal_error_deg = std::max(ev.max_normal_error_deg, err);
  }
  // expected adjacencies: significant gt faces touching along >= 3 grid cell edges
  std::map<std::pair<std::int32_t, std::int32_t>, int> touch;
  const auto& L = ev.cloud.labels;
  for (std::uint32_t r = 0; r < h; ++r) {
    for (std::uint32_t c = 0; c < w; ++c) {
      const std::size_t i = std::size_t(r) * w + c;
      for (std::size_t j : {c + 1 < w ? i + 1 : i, r + 1 < h ? i + w : i}) {
        if (j == i || L[i] < 0 || L[j] < 0 || L[i] == L[j]) continue;
        ++touch[{std::min(L[i], L[j]), std::max(L[i], L[j])}];
      }
    }
  }
  for (const auto& [p, cnt] : touch) {
    if (cnt < 3 || !ev.significant.count(p.first) || !ev.significant.count(p.second)) continue;
    auto a = ev.hoover.gt_correct_region.find(p.first), b = ev.hoover.gt_correct_region.find(p.second);
    if (a == ev.hoover.gt_correct_region.end() || b == ev.hoover.gt_correct_region.end()) continue;
    ev.expected_arcs.insert({std::min(a->second, b->second) + 1, std::max(a->second, b->second) + 1});
  }
  for (const auto& a : ev.graph.arcs)
    if (a.a != 0 && a.b != 0) ev.actual_arcs.insert({std::min(a.a, a.b), std::max(a.a, a.b)});
  return ev;
}

}  // namespace fs::test
