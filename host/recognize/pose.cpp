#include "host/recognize/pose.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>

namespace fs::host::rec {

namespace {

// The matched planes' normal equations n_s . t = d_s - d_m, each pair weighted by sqrt(its scene area):
// A t = b in least squares.
void plane_system(const Model& model, std::span<const PlanePair> pairs, Mat3& A, Vec3& b) {
  A = Mat3::Zero();
  b = Vec3::Zero();
  for (const PlanePair& p : pairs) {
    const ModelFace& f = model.faces[static_cast<std::size_t>(p.model_face)];
    const double w = std::sqrt(std::max(p.scene_area, 1e-9));
    A += w * p.scene_normal * p.scene_normal.transpose();
    b += w * p.scene_normal * (p.scene_offset - f.offset);
  }
}

// Sum of the squared plane residuals n_s . t - (d_s - d_m).
double plane_residual2(const Model& model, std::span<const PlanePair> pairs, const Vec3& t) {
  double r2 = 0.0;
  for (const PlanePair& p : pairs) {
    const ModelFace& f = model.faces[static_cast<std::size_t>(p.model_face)];
    const double r = p.scene_normal.dot(t) - (p.scene_offset - f.offset);
    r2 += r * r;
  }
  return r2;
}

}  // namespace

TranslationFit fit_translation(const Model& model, const Mat3& R, std::span<const PlanePair> pairs,
                               double min_eigen_ratio) {
  TranslationFit fit;
  Mat3 A;
  Vec3 b;
  plane_system(model, pairs, A, b);
  Vec3 centroid_shift = Vec3::Zero();
  double wsum = 0.0;
  for (const PlanePair& p : pairs) {
    const double w = std::sqrt(std::max(p.scene_area, 1e-9));
    centroid_shift +=
        w * (p.scene_centroid - R * model.faces[static_cast<std::size_t>(p.model_face)].centroid);
    wsum += w;
  }
  if (wsum <= 0.0) {
    fit.free_dims = 3;
    return fit;
  }
  centroid_shift /= wsum;
  Eigen::SelfAdjointEigenSolver<Mat3> es(A);
  const Vec3 ev = es.eigenvalues();  // ascending
  const double emax = std::max(ev(2), 1e-12);
  Vec3 t = Vec3::Zero();
  for (int k = 0; k < 3; ++k) {
    const Vec3 u = es.eigenvectors().col(k);
    if (ev(k) > min_eigen_ratio * emax) {
      t += u * (u.dot(b) / ev(k));
    } else {
      // Unconstrained by the planes: take the component from the centroid alignment.
      t += u * u.dot(centroid_shift);
      if (fit.free_dims == 0) fit.free_dir = u;
      ++fit.free_dims;
    }
  }
  fit.t = t;
  fit.rms_mm =
      pairs.empty() ? 0.0 : std::sqrt(plane_residual2(model, pairs, t) / static_cast<double>(pairs.size()));
  return fit;
}

double outside_face_mm(const ModelFace& f, const Vec3& q) {
  const Vec3 u = f.normal.unitOrthogonal();
  const Vec3 v = f.normal.cross(u);
  const double px = q.dot(u), py = q.dot(v);
  bool inside = false;
  double best2 = std::numeric_limits<double>::infinity();
  for (const auto& loop : f.loops) {
    if (loop.empty()) continue;
    double bx = loop.back().dot(u), by = loop.back().dot(v);
    for (const Vec3& p : loop) {
      const double ax = p.dot(u), ay = p.dot(v);
      if ((ay > py) != (by > py) && px < (bx - ax) * (py - ay) / (by - ay) + ax) inside = !inside;
      const double ex = bx - ax, ey = by - ay;
      const double t =
          std::clamp(((px - ax) * ex + (py - ay) * ey) / std::max(ex * ex + ey * ey, 1e-12), 0.0, 1.0);
      const double dx = ax + t * ex - px, dy = ay + t * ey - py;
      best2 = std::min(best2, dx * dx + dy * dy);
      bx = ax;
      by = ay;
    }
  }
  return inside ? 0.0 : std::sqrt(best2);
}

bool consistent_placement(const Model& model, const Mat3& R, std::span<const PlanePair> pairs,
                          const PlacementCheck& check) {
  // fit_translation's least squares without its centroid fill-in, with the closed-form 3 x 3 eigensolver:
  // this runs for every solution of every search.
  Mat3 A;
  Vec3 b;
  plane_system(model, pairs, A, b);
  Eigen::SelfAdjointEigenSolver<Mat3> es;
  es.computeDirect(A);
  const Vec3 ev = es.eigenvalues();  // ascending
  const double emax = std::max(ev(2), 1e-12);
  Vec3 t = Vec3::Zero();
  bool free = false;
  for (int k = 0; k < 3; ++k) {
    if (ev(k) > 0.02 * emax)
      t += es.eigenvectors().col(k) * (es.eigenvectors().col(k).dot(b) / ev(k));
    else
      free = true;
  }
  if (plane_residual2(model, pairs, t) > check.rms_mm * check.rms_mm * static_cast<double>(pairs.size()))
    return false;
  if (free) return true;  // where the faces lie along the free direction is not known: no outline test
  for (const PlanePair& p : pairs) {
    const ModelFace& f = model.faces[static_cast<std::size_t>(p.model_face)];
    if (outside_face_mm(f, R.transpose() * (p.scene_centroid - t)) > check.outside_mm) return false;
  }
  return true;
}

double rotation_angle_deg(const Mat3& R1, const Mat3& R2) {
  const double c = std::clamp(((R1.transpose() * R2).trace() - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(c) * 180.0 / M_PI;
}

double rotation_angle_deg_sym(const Mat3& R1, const Mat3& R2, const Model& model) {
  double best = rotation_angle_deg(R1, R2);
  for (const Mat3& S : model.symmetries) best = std::min(best, rotation_angle_deg(R1, R2 * S));
  return best;
}

void canonical_pose(const Model& model, Mat3& R, Vec3& t) {
  double best_trace = R.trace();
  Mat3 best_R = R;
  Vec3 best_t = t;
  for (const Mat3& S : model.symmetries) {
    const Mat3 RS = R * S;
    if (RS.trace() > best_trace + 1e-12) {
      best_trace = RS.trace();
      best_R = RS;
      best_t = t + R * (Mat3::Identity() - S) * model.center;
    }
  }
  R = best_R;
  t = best_t;
}

Mat3 nearest_rotation(const Mat3& M) {
  Eigen::JacobiSVD<Mat3> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 D = Mat3::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
  return svd.matrixU() * D * svd.matrixV().transpose();
}

}  // namespace fs::host::rec
