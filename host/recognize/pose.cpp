#include "host/recognize/pose.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

namespace fs::host::rec {

TranslationFit fit_translation(const Model& model, const Mat3& R, std::span<const PlanePair> pairs,
                               double min_eigen_ratio) {
  TranslationFit fit;
  Mat3 A = Mat3::Zero();
  Vec3 b = Vec3::Zero();
  Vec3 centroid_shift = Vec3::Zero();
  double wsum = 0.0;
  for (const PlanePair& p : pairs) {
    const ModelFace& f = model.faces[static_cast<std::size_t>(p.model_face)];
    const double w = std::sqrt(std::max(p.scene_area, 1e-9));
    A += w * p.scene_normal * p.scene_normal.transpose();
    b += w * p.scene_normal * (p.scene_offset - f.offset);
    centroid_shift += w * (p.scene_centroid - R * f.centroid);
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
  double r2 = 0.0;
  for (const PlanePair& p : pairs) {
    const ModelFace& f = model.faces[static_cast<std::size_t>(p.model_face)];
    const double r = p.scene_normal.dot(t) - (p.scene_offset - f.offset);
    r2 += r * r;
  }
  fit.rms_mm = pairs.empty() ? 0.0 : std::sqrt(r2 / static_cast<double>(pairs.size()));
  return fit;
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
