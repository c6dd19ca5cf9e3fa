#pragma once
// Triangulation accuracy on hw-sim scans (ground truth from the scene engineer's renderer / grid):
//  * end to end: render the stripe frame of a step with the renderer's noise model (RenderOptions, scaled by
//    noise_scale), extract the sub-pixel stripe with the firmware's extractor (default method), triangulate,
//    and compare each point with the renderer's true 3D point of that row;
//  * column noise only: the grid's true stripe columns plus Gaussian noise sigma_px, triangulated.
// Points more than gross_mm off (stripes straddling a depth edge, where the peak mixes two surfaces) are
// counted separately and excluded from rms_mm; rms_all_mm includes them.
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "firmware/extract/stripe_extractor.hpp"
#include "host/io/triangulate.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/scene.hpp"
#include "hw-sim/scene/stripe_renderer.hpp"
#include "render_extract.hpp"

namespace fs::test {

struct AccuracyResult {
  std::size_t points = 0;  // compared points
  std::size_t gross = 0;   // of which off by more than gross_mm
  double rms_mm = 0.0;     // without the gross ones
  double rms_all_mm = 0.0;
  double median_mm = 0.0;
  double p95_mm = 0.0;
};

inline AccuracyResult summarize(std::vector<double>& err, double gross_mm) {
  AccuracyResult r;
  r.points = err.size();
  if (err.empty()) return r;
  double sq = 0, sq_all = 0;
  std::size_t n = 0;
  for (double e : err) {
    sq_all += e * e;
    if (e > gross_mm) {
      ++r.gross;
    } else {
      sq += e * e;
      ++n;
    }
  }
  r.rms_mm = n ? std::sqrt(sq / double(n)) : 0.0;
  r.rms_all_mm = std::sqrt(sq_all / double(err.size()));
  std::sort(err.begin(), err.end());
  r.median_mm = err[err.size() / 2];
  r.p95_mm = err[std::min(err.size() - 1, err.size() * 95 / 100)];
  return r;
}

inline AccuracyResult end_to_end_accuracy(const sim::Scene& scene, double noise_scale,
                                          std::uint32_t step_stride, std::uint64_t seed,
                                          const host::TriangulationOptions& topt = {}, double gross_mm = 2.0,
                                          const fw::ExtractParams& extract = {}) {
  const auto& cal = scene.calibration;
  RenderExtract rx(scene, noise_scale, extract);
  host::Triangulator tri(cal, topt);
  host::OrganizedCloud cloud;
  tri.begin(cloud);
  host::TriangulationStats st;
  std::vector<double> err;
  for (std::uint32_t k = 0; k < cal.step_count; k += step_stride) {
    const std::uint32_t step = static_cast<std::uint32_t>(cal.first_step) + k;
    const auto counts = rx.step(step, seed + k);
    const auto pts = rx.points(counts);
    msg::StripeHeader h;
    h.step_index = step;
    tri.add_stripe(h, pts, cloud, st);
    const auto truth = rx.renderer().truth();
    for (const msg::StripePoint& pt : pts) {
      const auto row = pt.row;
      const auto& p = cloud.at(row, k);
      if (!host::OrganizedCloud::valid(p) || !truth[row].valid()) continue;
      err.push_back((p.cast<double>() - truth[row].point).norm());
    }
  }
  return summarize(err, gross_mm);
}

inline AccuracyResult column_noise_accuracy(const sim::GroundTruthGrid& gt, double sigma_px,
                                            std::uint64_t seed, const host::TriangulationOptions& topt = {},
                                            double gross_mm = 2.0) {
  const auto& cal = gt.calibration();
  host::Triangulator tri(cal, topt);
  host::OrganizedCloud cloud;
  tri.begin(cloud);
  host::TriangulationStats st;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<msg::StripePoint> pts;
  pts.reserve(gt.rows());
  std::vector<double> err;
  for (std::uint32_t k = 0; k < gt.steps(); ++k) {
    pts.clear();
    for (std::uint32_t r = 0; r < gt.rows(); ++r) {
      const auto& c = gt.at(k, r);
      if (!c.valid()) continue;
      pts.push_back(msg::StripePoint{static_cast<std::uint16_t>(r),
                                     static_cast<float>(c.column + sigma_px * noise(rng)), 200, 3.0f});
    }
    msg::StripeHeader h;
    h.step_index = static_cast<std::uint32_t>(gt.first_step()) + k;
    tri.add_stripe(h, pts, cloud, st);
    for (const auto& sp : pts) {
      const auto& p = cloud.at(sp.row, k);
      if (!host::OrganizedCloud::valid(p)) continue;
      err.push_back((p.cast<double>() - gt.at(k, sp.row).true_point).norm());
    }
  }
  return summarize(err, gross_mm);
}

}  // namespace fs::test
