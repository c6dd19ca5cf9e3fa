#pragma once
// Test helper: exact synthetic laser-stripe scans of a flat target. For each galvo step the true laser plane
// is intersected with the target plane z' = h (the table raised by h); for each image row the stripe column
// is where the projection of that line crosses the row (Newton on the line parameter), plus optional
// Gaussian sub-pixel noise. The true 3D point of every (row, step) is kept for accuracy checks.
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "common/calibration.hpp"
#include "common/messages.hpp"
#include "host/io/organized_cloud.hpp"
#include "host/io/scan.hpp"

namespace fs::test {

struct SynthStripe {
  msg::StripeHeader header;
  std::vector<msg::StripePoint> points;
};

struct SynthScan {
  msg::ScanBegin begin;
  std::vector<SynthStripe> stripes;
  msg::ScanEnd end;
  host::OrganizedCloud truth;  // step x row grid of true points (NaN where the stripe is off the image)
};

// Intersection line of two planes: point closest to `near` and unit direction.
inline bool plane_line(const Plane& a, const Plane& b, const Vec3& near, Vec3& p0, Vec3& dir) {
  dir = a.n.cross(b.n);
  if (dir.norm() < 1e-9) return false;
  dir.normalize();
  // Solve for the point on both planes closest to `near`: minimize |x - near|^2 s.t. a.n x = a.d, b.n x =
  // b.d.
  Eigen::Matrix<double, 2, 3> N;
  N.row(0) = a.n.transpose();
  N.row(1) = b.n.transpose();
  const Eigen::Vector2d rhs(a.d - a.n.dot(near), b.d - b.n.dot(near));
  p0 = near + N.transpose() * (N * N.transpose()).ldlt().solve(rhs);
  return true;
}

inline SynthScan synth_flat_scan(const ScannerCalibration& truth,
                                 const ScannerCalibration& header_calibration, double height, double noise_px,
                                 std::uint64_t seed, std::uint64_t scan_id = 1,
                                 std::uint32_t row_stride = 1) {
  SynthScan s;
  s.begin.scan_id = scan_id;
  s.begin.scanner_model = "synthetic";
  s.begin.calibration = header_calibration;
  const auto& cam = truth.camera;
  s.truth.reset(truth.step_count, cam.height);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_px > 0 ? noise_px : 1.0);
  const Plane target{truth.table.n, truth.table.d + height};
  for (std::uint32_t k = 0; k < truth.step_count; ++k) {
    SynthStripe st;
    st.header.scan_id = scan_id;
    st.header.step_index = static_cast<std::uint32_t>(truth.first_step + static_cast<std::int32_t>(k));
    st.header.commanded_angle = truth.laser.mirror_angle(st.header.step_index);
    st.header.measured_position = st.header.step_index;
    st.header.frame_sequence = k;
    const Plane laser = truth.laser.plane_at_step(st.header.step_index);
    Vec3 p0, dir;
    if (plane_line(laser, target, cam.center(), p0, dir)) {
      auto v_of = [&](double t, Vec2& px) { return cam.project(p0 + t * dir, px); };
      // Make v increase with t.
      Vec2 a, b;
      if (v_of(0.0, a) && v_of(1.0, b) && b.y() < a.y()) dir = -dir;
      double t = 0.0;  // warm start from the previous row
      for (std::uint32_t r = 0; r < cam.height; r += row_stride) {
        Vec2 px;
        bool ok = false;
        for (int it = 0; it < 30; ++it) {
          Vec2 pa, pb;
          if (!v_of(t, px) || !v_of(t - 0.5, pa) || !v_of(t + 0.5, pb)) break;
          const double dv = pb.y() - pa.y();
          if (std::abs(dv) < 1e-12) break;
          const double dt = (r - px.y()) / dv;
          t += std::clamp(dt, -2000.0, 2000.0);
          if (std::abs(dt) < 1e-9) {
            ok = v_of(t, px);
            break;
          }
        }
        if (!ok || std::abs(px.y() - r) > 1e-6 || px.x() < 0.5 || px.x() > cam.width - 1.5) continue;
        msg::StripePoint sp;
        sp.row = static_cast<std::uint16_t>(r);
        sp.col = static_cast<float>(px.x() + (noise_px > 0 ? noise(rng) : 0.0));
        sp.peak = 200;
        sp.width = 3.0f;
        st.points.push_back(sp);
        s.truth.at(r, k) = (p0 + t * dir).cast<float>();
      }
    }
    s.stripes.push_back(std::move(st));
  }
  s.end.scan_id = scan_id;
  s.end.stripes_sent = truth.step_count;
  s.end.frames_captured = truth.step_count;
  s.end.completed = 1;
  return s;
}

// Feeds a synthetic scan into a Scan object (as the assembler would).
inline void fill_scan(const SynthScan& s, host::Scan& out) {
  out.start(s.begin);
  for (const auto& st : s.stripes) {
    msg::Stripe m;
    m.header = st.header;
    m.points = std::span<msg::StripePoint>(const_cast<msg::StripePoint*>(st.points.data()), st.points.size());
    out.add_stripe(m);
  }
  out.finish(s.end);
}

// A perturbed copy of the default geometry (what the real bench might be).
inline ScannerCalibration perturbed_truth(const ScannerCalibration& nominal) {
  ScannerCalibration t = nominal;
  t.laser.axis_point += Vec3(1.5, 0.0, -2.0);
  t.laser.axis_dir = (t.laser.axis_dir + Vec3(0.006, 0.0, 0.004)).normalized();
  const Vec3 n0 = t.laser.normal_at_zero - t.laser.normal_at_zero.dot(t.laser.axis_dir) * t.laser.axis_dir;
  t.laser.normal_at_zero = n0.normalized();
  t.laser.mirror_angle_at_step0 += 0.003;
  t.laser.rad_per_step *= 1.004;
  return t;
}

}  // namespace fs::test
