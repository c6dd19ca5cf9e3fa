#include "host/io/triangulate.hpp"

#include <algorithm>
#include <cmath>

#include "common/error.hpp"
#include "host/io/scan.hpp"

namespace fs::host {

bool same_camera(const CameraModel& a, const CameraModel& b) {
  return a.width == b.width && a.height == b.height && a.fx == b.fx && a.fy == b.fy && a.cx == b.cx &&
         a.cy == b.cy && a.k1 == b.k1 && a.k2 == b.k2 && a.k3 == b.k3 && a.p1 == b.p1 && a.p2 == b.p2 &&
         a.R_world_cam == b.R_world_cam && a.t_world_cam == b.t_world_cam;
}

bool same_calibration(const ScannerCalibration& a, const ScannerCalibration& b) {
  const auto& la = a.laser;
  const auto& lb = b.laser;
  return same_camera(a.camera, b.camera) && la.axis_point == lb.axis_point && la.axis_dir == lb.axis_dir &&
         la.normal_at_zero == lb.normal_at_zero && la.optical_gain == lb.optical_gain &&
         la.mirror_angle_at_step0 == lb.mirror_angle_at_step0 && la.rad_per_step == lb.rad_per_step &&
         a.first_step == b.first_step && a.step_count == b.step_count;
}

void Triangulator::configure(const ScannerCalibration& c, const TriangulationOptions& options) {
  const auto& cam = c.camera;
  static_assert(sizeof(Ray) == ScanLimits::kRayBytes && sizeof(StepPlane) == ScanLimits::kPlaneBytes,
                "the memory model's bytes per ray and per plane");
  options.limits.check_camera(c, "calibration");  // before anything is allocated
  if (!(cam.fx > 0) || !(cam.fy > 0)) throw Error("calibration: focal lengths must be positive");
  const bool camera_changed = !configured_ || !same_camera(cam, calib_.camera);
  calib_ = c;
  options_ = options;
  const double s = std::sin(options.min_ray_plane_angle_deg * M_PI / 180.0);
  sin2_min_ = static_cast<float>(s * s);
  max_range2_ = static_cast<float>(options.max_range_mm * options.max_range_mm);
  centre_ = cam.t_world_cam.cast<float>();
  if (camera_changed) {
    rows_ = cam.height;
    cols_ = cam.width;
    rays_.resize(std::size_t(rows_) * (cols_ + 1));
    row_stamp_.assign(rows_, 0);
    row_peak_.assign(rows_, 0);
    stamp_ = 0;
    const Mat3& R = cam.R_world_cam;
    const double k1 = cam.k1, k2 = cam.k2, k3 = cam.k3, p1 = cam.p1, p2 = cam.p2;
    for (std::uint32_t r = 0; r < rows_; ++r) {
      // Undistort by fixed-point iteration (as CameraModel::undistort_pixel), warm-started from the
      // neighbouring pixel's solution so that a few iterations suffice.
      const Vec2 start = cam.undistort_pixel(Vec2(0.0, r));
      double x = start.x(), y = start.y();
      const double yd = (r - cam.cy) / cam.fy;
      Ray* row = rays_.data() + std::size_t(r) * (cols_ + 1);
      for (std::uint32_t col = 0; col <= cols_; ++col) {
        const double xd = (col - cam.cx) / cam.fx;
        for (int it = 0; it < 50; ++it) {
          const double r2 = x * x + y * y;
          const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
          const double ex = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) - xd;
          const double ey = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y - yd;
          x -= ex;
          y -= ey;
          if (ex * ex + ey * ey < 1e-26) break;
        }
        const double dx = R(0, 0) * x + R(0, 1) * y + R(0, 2);
        const double dy = R(1, 0) * x + R(1, 1) * y + R(1, 2);
        const double dz = R(2, 0) * x + R(2, 1) * y + R(2, 2);
        row[col] = Ray{float(dx), float(dy), float(dz)};
      }
    }
  }
  if (smoothed_.size() < msg::kMaxStripePoints) smoothed_.resize(msg::kMaxStripePoints);
  planes_.resize(c.step_count);
  for (std::uint32_t k = 0; k < c.step_count; ++k) planes_[k] = plane_for(double(c.first_step) + k);
  configured_ = true;
}

Triangulator::StepPlane Triangulator::plane_for(double step) const {
  const Plane p = calib_.laser.plane_at_step(step);
  const double e = p.d - p.n.dot(calib_.camera.t_world_cam);
  return StepPlane{float(p.n.x()), float(p.n.y()), float(p.n.z()), float(e)};
}

void Triangulator::begin(OrganizedCloud& out) const {
  if (!configured_) throw Error("triangulator used before configure()");
  out.reset(calib_.step_count, rows_, false);
  out.viewpoint = calib_.camera.t_world_cam;
  out.viewpoint_orientation = Eigen::Quaterniond(calib_.camera.R_world_cam);
  out.scanner = calib_;
}

void Triangulator::add_stripe(const msg::StripeHeader& header, std::span<const msg::StripePoint> points,
                              OrganizedCloud& out, TriangulationStats& stats) const {
  const std::int64_t column = std::int64_t(header.step_index) - calib_.first_step;
  if (column < 0 || column >= std::int64_t(calib_.step_count) || out.width != calib_.step_count ||
      out.height != rows_) {
    stats.out_of_image += points.size();
    return;
  }
  const StepPlane pl = options_.use_measured_position ? plane_for(header.measured_position)
                                                      : planes_[static_cast<std::size_t>(column)];
  const float cmax = float(cols_ - 1);
  const std::size_t stride = cols_ + 1;
  const Ray* rays = rays_.data();
  Eigen::Vector3f* dst = out.points.data() + column;
  const std::size_t width = out.width;
  std::uint64_t ok = 0, outside = 0, grazing = 0, range = 0;
  const float* cols = smooth_columns(points);
  if (++stamp_ == 0) {  // wrapped: forget every row's owner
    std::fill(row_stamp_.begin(), row_stamp_.end(), 0u);
    stamp_ = 1;
  }
  const std::uint32_t stamp = stamp_;
  std::uint32_t* row_stamp = row_stamp_.data();
  std::uint16_t* row_peak = row_peak_.data();
  std::uint64_t shared = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const msg::StripePoint& sp = points[i];
    const float col = cols ? cols[i] : sp.col;
    if (sp.row >= rows_ || !(col >= 0.0f && col <= cmax)) {
      ++outside;
      continue;
    }
    const std::uint32_t c0 = static_cast<std::uint32_t>(col);
    const float f = col - float(c0);
    const Ray& a = rays[sp.row * stride + c0];
    const Ray& b = rays[sp.row * stride + c0 + 1];
    const float dx = a.x + f * (b.x - a.x), dy = a.y + f * (b.y - a.y), dz = a.z + f * (b.z - a.z);
    const float den = pl.nx * dx + pl.ny * dy + pl.nz * dz;
    const float d2 = dx * dx + dy * dy + dz * dz;
    if (den * den < sin2_min_ * d2) {
      ++grazing;
      continue;
    }
    const float s = pl.e / den;
    if (!(s > 0.0f) || s * s * d2 > max_range2_) {
      ++range;
      continue;
    }
    if (row_stamp[sp.row] == stamp) {  // the row's cell already holds a point of this stripe
      ++shared;
      if (sp.peak <= row_peak[sp.row]) continue;  // the brightest stays (the first on a tie)
    } else {
      ++ok;
    }
    row_stamp[sp.row] = stamp;
    row_peak[sp.row] = sp.peak;
    dst[sp.row * width] = Eigen::Vector3f(centre_.x() + s * dx, centre_.y() + s * dy, centre_.z() + s * dz);
  }
  stats.points += ok;
  stats.out_of_image += outside;
  stats.grazing += grazing;
  stats.out_of_range += range;
  stats.shared_cell += shared;
}

const float* Triangulator::smooth_columns(std::span<const msg::StripePoint> points) const {
  const int w = static_cast<int>(options_.smooth_half_window);
  if (w == 0 || points.size() < 3) return nullptr;
  if (smoothed_.size() < points.size()) smoothed_.resize(points.size());  // only for oversized stripes
  const float jump = options_.smooth_max_jump_px;
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(points.size());
  const msg::StripePoint* pt = points.data();
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const float ci = pt[i].col;
    const int ri = pt[i].row;
    // Fast path: a full window of consecutive rows without a jump. The straight-line fit evaluated at the
    // centre of a symmetric window is the window's mean.
    if (i >= w && i + w < n && int(pt[i + w].row) - int(pt[i - w].row) == 2 * w) {
      float sum = pt[i - w].col;
      bool smooth = true;
      for (std::ptrdiff_t j = i - w + 1; j <= i + w; ++j) {
        smooth &= std::abs(pt[j].col - pt[j - 1].col) <= jump;
        sum += pt[j].col;
      }
      if (smooth) {
        smoothed_[static_cast<std::size_t>(i)] = sum / float(2 * w + 1);
        continue;
      }
    }
    // Sums over the window of d = row offset and c = column offset from point i (well conditioned).
    float sn = 1, sd = 0, sdd = 0, sc = 0, scd = 0;
    for (int dir = -1; dir <= 1; dir += 2) {
      float prev = ci;
      for (std::ptrdiff_t j = i + dir; j >= 0 && j < n; j += dir) {
        const auto& q = points[static_cast<std::size_t>(j)];
        const int d = int(q.row) - ri;
        if (d * dir > w || d == 0 || !(std::abs(q.col - prev) <= jump)) break;
        const float c = q.col - ci;
        sn += 1;
        sd += float(d);
        sdd += float(d * d);
        sc += c;
        scd += c * float(d);
        prev = q.col;
      }
    }
    const float det = sn * sdd - sd * sd;
    smoothed_[static_cast<std::size_t>(i)] = (sn >= 3 && det > 0.5f) ? ci + (sdd * sc - sd * scd) / det : ci;
  }
  return smoothed_.data();
}

void Triangulator::release() {
  rays_ = std::vector<Ray>();
  planes_ = std::vector<StepPlane>();
  smoothed_ = std::vector<float>();
  row_stamp_ = std::vector<std::uint32_t>();
  row_peak_ = std::vector<std::uint16_t>();
  stamp_ = 0;
  rows_ = cols_ = 0;
  configured_ = false;
}

std::uint64_t Triangulator::table_bytes() const {
  return rays_.capacity() * sizeof(Ray) + planes_.capacity() * sizeof(StepPlane) +
         smoothed_.capacity() * sizeof(float) + row_stamp_.capacity() * sizeof(std::uint32_t) +
         row_peak_.capacity() * sizeof(std::uint16_t);
}

TriangulationStats Triangulator::triangulate(const Scan& scan, OrganizedCloud& out) {
  const ScannerCalibration& c = scan.begin_message().calibration;
  if (!configured_ || !same_calibration(c, calib_)) configure(c, options_);
  TriangulationStats stats;
  begin(out);
  for (std::uint32_t k = 0; k < scan.slot_count(); ++k) {
    if (!scan.has_stripe(k)) continue;
    add_stripe(scan.stripe_header(k), scan.stripe_points(k), out, stats);
  }
  return stats;
}

bool Triangulator::triangulate_point(const ScannerCalibration& c, double step, double row, double col,
                                     double cos_min, Vec3& out) {
  const Vec3 dir = c.camera.ray_world(Vec2(col, row));
  return intersect_ray_plane(c.camera.center(), dir, c.laser.plane_at_step(step), cos_min, out);
}

}  // namespace fs::host
