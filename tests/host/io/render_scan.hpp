#pragma once
// Test helper: laser scans rendered by hw-sim instead of computed exactly. Each step's camera frame is drawn
// by the scene renderer (hw-sim/scene/stripe_renderer.hpp, its noise model scaled by noise_scale) with the
// scene's TRUE geometry, the stripe is extracted by the firmware's extractor (default sub-pixel method), and
// the scan header carries whatever calibration the caller says the scanner believes in (the nominal one
// before calibration). The renderer's true 3D point of every (row, step) is kept in SynthScan::truth.
//
// Scenes for laser calibration: a flat plate (a box mesh far larger than the field of view) of a given height
// on the table, or the bare table for height 0.
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "firmware/extract/stripe_extractor.hpp"
#include "fscan_file.hpp"
#include "host/io/triangulate.hpp"
#include "hw-sim/scene/scene.hpp"
#include "hw-sim/scene/stripe_renderer.hpp"
#include "render_extract.hpp"
#include "synth_scan.hpp"

namespace fs::test {

// A box of size 2a x 2b x h, its bottom on z = 0 (faces counter-clockwise seen from outside).
inline Mesh plate_mesh(double a, double b, double h) {
  Mesh m;
  m.name = "plate";
  for (double z : {0.0, h})
    for (const auto& xy : {Vec2(-a, -b), Vec2(a, -b), Vec2(a, b), Vec2(-a, b)})
      m.vertices.emplace_back(xy.x(), xy.y(), z);
  m.faces = {{4, 5, 6, 7}, {0, 3, 2, 1}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
  return m;
}

// The flat target `height` mm above the table, scanned with the true geometry `truth`. The plate (800 x 700
// mm) covers everything the camera sees, so every stripe point lies on its top face.
inline sim::Scene flat_target_scene(const ScannerCalibration& truth, double height) {
  sim::Scene s;
  s.calibration = truth;
  s.source = "flat target " + std::to_string(height) + " mm";
  if (height > 0.0) sim::add_object(s, plate_mesh(400.0, 350.0, height), Mat3::Identity(), Vec3::Zero());
  return s;
}

// Renders every step of the scene's calibration (stride 1) into a scan whose header holds
// `header_calibration`.
inline SynthScan render_scan(const sim::Scene& scene, const ScannerCalibration& header_calibration,
                             double noise_scale, std::uint64_t seed, std::uint64_t scan_id = 1) {
  const auto& cal = scene.calibration;
  RenderExtract rx(scene, noise_scale);
  SynthScan s;
  s.begin.scan_id = scan_id;
  s.begin.scanner_model = "hw-sim render";
  s.begin.calibration = header_calibration;
  s.truth.reset(cal.step_count, cal.camera.height);
  s.truth.viewpoint = cal.camera.center();
  for (std::uint32_t k = 0; k < cal.step_count; ++k) {
    const std::uint32_t step = static_cast<std::uint32_t>(cal.first_step + static_cast<std::int32_t>(k));
    const auto counts = rx.step(step, seed * 1000003u + k);
    SynthStripe st;
    st.header.scan_id = scan_id;
    st.header.step_index = step;
    st.header.commanded_angle = header_calibration.laser.mirror_angle(step);
    st.header.measured_position = step;
    st.header.frame_sequence = k;
    st.header.flags = counts.header_flags();
    const auto pts = rx.points(counts);
    st.points.assign(pts.begin(), pts.end());
    const auto truth = rx.renderer().truth();
    for (std::uint32_t r = 0; r < cal.camera.height; ++r)
      if (truth[r].valid()) s.truth.at(r, k) = truth[r].point.cast<float>();
    s.stripes.push_back(std::move(st));
  }
  s.end.scan_id = scan_id;
  s.end.stripes_sent = cal.step_count;
  s.end.frames_captured = cal.step_count;
  s.end.completed = 1;
  return s;
}

struct ModelError {
  std::size_t points = 0;  // triangulated points with a true point
  std::size_t gross = 0;   // of which more than gross_mm off (stripes straddling a depth edge)
  double rms_mm = 0.0;     // without the gross ones
  double rms_all_mm = 0.0;
};

// Triangulates the scan's stripes with `model` (default options: stripe smoothing on) and compares every
// point with the true one.
inline ModelError model_error(const SynthScan& s, const ScannerCalibration& model, double gross_mm = 2.0) {
  host::Triangulator tri(model);
  host::OrganizedCloud cloud;
  tri.begin(cloud);
  host::TriangulationStats st;
  for (const auto& stripe : s.stripes) tri.add_stripe(stripe.header, stripe.points, cloud, st);
  ModelError e;
  double sq = 0, sq_all = 0;
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    if (!host::OrganizedCloud::valid(cloud.points[i]) || !host::OrganizedCloud::valid(s.truth.points[i]))
      continue;
    const double d2 = (cloud.points[i] - s.truth.points[i]).cast<double>().squaredNorm();
    ++e.points;
    sq_all += d2;
    if (d2 > gross_mm * gross_mm)
      ++e.gross;
    else
      sq += d2;
  }
  if (e.points) e.rms_all_mm = std::sqrt(sq_all / double(e.points));
  if (e.points > e.gross) e.rms_mm = std::sqrt(sq / double(e.points - e.gross));
  return e;
}

}  // namespace fs::test

namespace fs::test {

// RMS distance (mm) between the points triangulated from the same stripes with two models: the error due to
// the model alone, without the extraction noise both share.
inline double model_difference(const SynthScan& s, const ScannerCalibration& a, const ScannerCalibration& b) {
  host::TriangulationOptions raw;
  raw.smooth_half_window = 0;
  host::Triangulator ta(a, raw), tb(b, raw);
  host::OrganizedCloud ca, cb;
  ta.begin(ca);
  tb.begin(cb);
  host::TriangulationStats st;
  for (const auto& stripe : s.stripes) {
    ta.add_stripe(stripe.header, stripe.points, ca, st);
    tb.add_stripe(stripe.header, stripe.points, cb, st);
  }
  double sq = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < ca.points.size(); ++i) {
    if (!host::OrganizedCloud::valid(ca.points[i]) || !host::OrganizedCloud::valid(cb.points[i])) continue;
    sq += (ca.points[i] - cb.points[i]).cast<double>().squaredNorm();
    ++n;
  }
  return n ? std::sqrt(sq / double(n)) : 0.0;
}

}  // namespace fs::test
