#include "host/io/calibrate.hpp"

#include <cmath>
#include <map>

#include <Eigen/Dense>

#include "common/error.hpp"

namespace fs::host {
namespace {

struct Obs {
  double step;
  Vec3 ray;  // unit, world frame, from the camera centre
  int target;
};

struct Problem {
  Vec3 centre;
  Plane table;
  std::vector<double> heights;
  std::vector<Obs> obs;
};

// Residual: signed distance (mm) of the triangulated point from its target plane. A ray (nearly) parallel
// to the laser plane gets a large constant residual.
double residual(const LaserModel& m, const Problem& p, const Obs& o) {
  const Plane pl = m.plane_at_step(o.step);
  Vec3 x;
  if (!intersect_ray_plane(p.centre, o.ray, pl, 1e-6, x)) return 1e3;
  return p.table.n.dot(x) - p.table.d - p.heights[static_cast<std::size_t>(o.target)];
}

void residuals(const LaserModel& m, const Problem& p, Eigen::VectorXd& r) {
  r.resize(static_cast<Eigen::Index>(p.obs.size()));
  for (std::size_t i = 0; i < p.obs.size(); ++i) r[static_cast<Eigen::Index>(i)] = residual(m, p, p.obs[i]);
}

void perpendicular_basis(const Vec3& a, Vec3& e1, Vec3& e2) {
  const Vec3 helper = std::abs(a.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  e1 = a.cross(helper).normalized();
  e2 = a.cross(e1).normalized();
}

// The 6-parameter update of a laser model (see calibrate.hpp).
LaserModel apply(const LaserModel& m, const Eigen::Matrix<double, 6, 1>& d) {
  LaserModel out = m;
  const Vec3 a = m.axis_dir.normalized();
  Vec3 e1, e2;
  perpendicular_basis(a, e1, e2);
  out.axis_dir = (a + d[0] * e1 + d[1] * e2).normalized();
  out.axis_point = m.axis_point + d[2] * e1 + d[3] * e2;
  const Vec3 n0 = m.normal_at_zero - m.normal_at_zero.dot(out.axis_dir) * out.axis_dir;
  out.normal_at_zero = n0.normalized();
  out.mirror_angle_at_step0 = m.mirror_angle_at_step0 + d[4];
  out.rad_per_step = m.rad_per_step * (1.0 + d[5]);
  return out;
}

double rms(const Eigen::VectorXd& r) {
  return r.size() ? std::sqrt(r.squaredNorm() / double(r.size())) : 0.0;
}

// Linear estimate: per-step planes from the points on the targets, the common axis, angle vs. step.
LaserModel linear_init(const LaserModel& nominal, const Problem& p) {
  struct Acc {
    Vec3 sum = Vec3::Zero();
    Mat3 outer = Mat3::Zero();
    std::size_t n = 0;
    std::uint32_t targets_mask = 0;
  };
  std::map<double, Acc> steps;  // per galvo step, over all targets
  for (const Obs& o : p.obs) {
    const Plane target{p.table.n, p.table.d + p.heights[static_cast<std::size_t>(o.target)]};
    Vec3 x;
    if (!intersect_ray_plane(p.centre, o.ray, target, 1e-6, x)) continue;
    Acc& a = steps[o.step];
    a.sum += x;
    a.outer += x * x.transpose();
    ++a.n;
    a.targets_mask |= 1u << (o.target % 32);
  }
  struct StepPlane {
    double step;
    Vec3 n;
    double d;
    double weight;
  };
  std::vector<StepPlane> planes;
  for (const auto& [step, a] : steps) {
    if (a.n < 6 || (a.targets_mask & (a.targets_mask - 1)) == 0) continue;  // needs >= 2 heights
    const Vec3 c = a.sum / double(a.n);
    const Mat3 cov = a.outer / double(a.n) - c * c.transpose();
    Eigen::SelfAdjointEigenSolver<Mat3> es(cov);
    if (es.eigenvalues()[1] < 1e-6 * es.eigenvalues()[2]) continue;  // collinear
    Vec3 n = es.eigenvectors().col(0);
    const Vec3 n_nom = nominal.plane_at_step(step).n;
    if (n.dot(n_nom) < 0) n = -n;
    planes.push_back({step, n, n.dot(c), double(a.n)});
  }
  if (planes.size() < 3) throw Error("calibrate: fewer than 3 galvo steps seen on 2 or more target heights");
  Mat3 M = Mat3::Zero();
  for (const auto& s : planes) M += s.weight * s.n * s.n.transpose();
  Eigen::SelfAdjointEigenSolver<Mat3> es(M);
  Vec3 axis = es.eigenvectors().col(0);
  if (axis.dot(nominal.axis_dir) < 0) axis = -axis;
  if (es.eigenvalues()[1] < 1e-9 * es.eigenvalues()[2])
    throw Error("calibrate: the step planes are (nearly) parallel; the galvo axis is not determined");
  // Axis point: least squares of n_k . P = d_k, pinned along the axis to the nominal point's position.
  Mat3 A = axis * axis.transpose();
  Vec3 b = axis * axis.dot(nominal.axis_point);
  for (const auto& s : planes) {
    A += s.weight * s.n * s.n.transpose() / double(p.obs.size());
    b += s.weight * s.n * s.d / double(p.obs.size());
  }
  LaserModel m = nominal;
  m.axis_dir = axis;
  m.axis_point = A.ldlt().solve(b);
  Vec3 n0 = nominal.normal_at_zero - nominal.normal_at_zero.dot(axis) * axis;
  m.normal_at_zero = n0.normalized();
  // Plane angle phi_k of each step about the axis, then phi = gain * (a0 + r * step).
  double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (const auto& s : planes) {
    const Vec3 nk = (s.n - s.n.dot(axis) * axis).normalized();
    const double phi = std::atan2(m.normal_at_zero.cross(nk).dot(axis), m.normal_at_zero.dot(nk));
    sw += s.weight;
    sx += s.weight * s.step;
    sy += s.weight * phi;
    sxx += s.weight * s.step * s.step;
    sxy += s.weight * s.step * phi;
  }
  const double den = sw * sxx - sx * sx;
  if (std::abs(den) < 1e-12) throw Error("calibrate: all observations come from a single galvo step");
  const double slope = (sw * sxy - sx * sy) / den;
  const double icpt = (sy - slope * sx) / sw;
  m.rad_per_step = slope / m.optical_gain;
  m.mirror_angle_at_step0 = icpt / m.optical_gain;
  return m;
}

}  // namespace

CalibrationResult calibrate_laser(const ScannerCalibration& nominal, const std::vector<FlatTarget>& targets,
                                  const CalibrateOptions& options) {
  if (targets.size() < 2) throw Error("calibrate: need scans of the flat target at 2 or more heights");
  Problem p;
  p.centre = nominal.camera.center();
  p.table = nominal.table;
  const std::uint32_t stride = std::max<std::uint32_t>(1, options.row_stride);
  for (std::size_t t = 0; t < targets.size(); ++t) {
    const FlatTarget& tg = targets[t];
    if (!tg.scan || !tg.scan->started()) throw Error("calibrate: target " + tg.name + " has no scan");
    for (std::size_t u = 0; u < t; ++u)
      if (std::abs(targets[u].height_mm - tg.height_mm) < 1e-9)
        throw Error("calibrate: targets " + targets[u].name + " and " + tg.name + " have the same height");
    p.heights.push_back(tg.height_mm);
    const Scan& s = *tg.scan;
    for (std::uint32_t k = 0; k < s.slot_count(); ++k) {
      if (!s.has_stripe(k)) continue;
      const auto pts = s.stripe_points(k);
      const double step = double(s.stripe_header(k).step_index);
      for (std::size_t i = 0; i < pts.size(); i += stride) {
        const auto& sp = pts[i];
        if (!std::isfinite(sp.col) || sp.col < 0 || sp.col > float(nominal.camera.width - 1) ||
            sp.row >= nominal.camera.height)
          continue;
        p.obs.push_back(Obs{step, nominal.camera.ray_world(Vec2(sp.col, sp.row)), static_cast<int>(t)});
      }
    }
  }
  if (p.obs.size() < 50)
    throw Error("calibrate: only " + std::to_string(p.obs.size()) + " stripe points on the targets");

  CalibrationResult res;
  Eigen::VectorXd r;
  residuals(nominal.laser, p, r);
  res.rms_before_mm = rms(r);
  std::vector<double> before_sq(targets.size(), 0.0);
  std::vector<std::size_t> before_n(targets.size(), 0);
  for (std::size_t i = 0; i < p.obs.size(); ++i) {
    before_sq[static_cast<std::size_t>(p.obs[i].target)] +=
        r[static_cast<Eigen::Index>(i)] * r[static_cast<Eigen::Index>(i)];
    ++before_n[static_cast<std::size_t>(p.obs[i].target)];
  }

  LaserModel m = options.linear_init ? linear_init(nominal.laser, p) : nominal.laser;
  residuals(m, p, r);
  res.rms_init_mm = rms(r);
  // Drop gross outliers (stray reflections, points off the target).
  std::vector<Obs> kept;
  kept.reserve(p.obs.size());
  for (std::size_t i = 0; i < p.obs.size(); ++i)
    if (std::abs(r[static_cast<Eigen::Index>(i)]) <= options.outlier_mm) kept.push_back(p.obs[i]);
  res.outliers = p.obs.size() - kept.size();
  if (kept.size() < 50)
    throw Error("calibrate: too few points within " + std::to_string(options.outlier_mm) +
                " mm of the targets");
  p.obs.swap(kept);

  // Levenberg-Marquardt with forward-difference Jacobian.
  const double h[6] = {1e-7, 1e-7, 1e-5, 1e-5, 1e-8, 1e-7};
  residuals(m, p, r);
  double cost = r.squaredNorm();
  double lambda = 1e-3;
  Eigen::MatrixXd J(r.size(), 6);
  Eigen::VectorXd rp;
  int it = 0;
  for (; it < options.max_iterations; ++it) {
    for (int k = 0; k < 6; ++k) {
      Eigen::Matrix<double, 6, 1> d = Eigen::Matrix<double, 6, 1>::Zero();
      d[k] = h[k];
      residuals(apply(m, d), p, rp);
      J.col(k) = (rp - r) / h[k];
    }
    const Eigen::Matrix<double, 6, 6> JtJ = J.transpose() * J;
    const Eigen::Matrix<double, 6, 1> g = J.transpose() * r;
    bool improved = false;
    for (int tries = 0; tries < 12 && !improved; ++tries) {
      Eigen::Matrix<double, 6, 6> A = JtJ;
      for (int k = 0; k < 6; ++k) A(k, k) += lambda * std::max(JtJ(k, k), 1e-12);
      const Eigen::Matrix<double, 6, 1> step = A.ldlt().solve(-g);
      const LaserModel cand = apply(m, step);
      residuals(cand, p, rp);
      const double c2 = rp.squaredNorm();
      if (c2 < cost) {
        const double rel = (cost - c2) / std::max(cost, 1e-300);
        m = cand;
        r = rp;
        cost = c2;
        lambda = std::max(lambda * 0.2, 1e-12);
        improved = true;
        if (rel < 1e-9) it = options.max_iterations;  // converged (relative cost change)
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) break;
  }
  res.iterations = std::min(it, options.max_iterations);
  res.calibration = nominal;
  res.calibration.laser = m;
  res.rms_after_mm = rms(r);
  res.max_after_mm = r.size() ? r.cwiseAbs().maxCoeff() : 0.0;
  res.points = p.obs.size();
  res.targets.resize(targets.size());
  for (std::size_t t = 0; t < targets.size(); ++t) {
    auto& tr = res.targets[t];
    tr.name = targets[t].name;
    tr.height_mm = targets[t].height_mm;
    tr.rms_before_mm = before_n[t] ? std::sqrt(before_sq[t] / double(before_n[t])) : 0.0;
  }
  std::vector<double> sq(targets.size(), 0.0);
  for (std::size_t i = 0; i < p.obs.size(); ++i) {
    const auto t = static_cast<std::size_t>(p.obs[i].target);
    const double v = r[static_cast<Eigen::Index>(i)];
    sq[t] += v * v;
    ++res.targets[t].points;
    res.targets[t].max_after_mm = std::max(res.targets[t].max_after_mm, std::abs(v));
  }
  for (std::size_t t = 0; t < targets.size(); ++t)
    res.targets[t].rms_after_mm =
        res.targets[t].points ? std::sqrt(sq[t] / double(res.targets[t].points)) : 0.0;
  return res;
}

}  // namespace fs::host
