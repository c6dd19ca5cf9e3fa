#pragma once
// Pose of a recognized model: x_scene = R x_model + t (mm).
//  * translation from matched planes: n_s . t = d_s - d_m (least squares over matched faces, weighted by
//    sqrt(area)); when the matched normals do not span 3D the free directions are filled from the face
//    centroids and reported;
//  * rotation distances and the canonical representative of a pose under the model's symmetry group.
#include <span>

#include "common/calibration.hpp"
#include "host/library/model.hpp"
#include "host/pfrg/pfrg.hpp"

namespace fs::host::rec {

struct PlanePair {
  Vec3 scene_normal;    // unit
  double scene_offset;  // n_s . y = d_s
  Vec3 scene_centroid;
  double scene_area;
  int model_face;  // index into Model::faces
};

// A matched scene face (with its plane) and the model face it stands for.
inline PlanePair plane_pair(const PfrgNode& scene_face, int model_face) {
  return {scene_face.normal, scene_face.offset, scene_face.centroid, scene_face.area, model_face};
}

struct TranslationFit {
  Vec3 t = Vec3::Zero();
  int free_dims = 0;             // 0 = determined by the planes; 1 or 2 = filled in from centroids
  Vec3 free_dir = Vec3::Zero();  // a unit direction the planes do not constrain (free_dims >= 1)
  double rms_mm = 0.0;           // rms plane residual n_s . t - (d_s - d_m)
};

TranslationFit fit_translation(const Model& model, const Mat3& R, std::span<const PlanePair> pairs,
                               double min_eigen_ratio = 0.02);

// How far point q (model frame), projected onto face f's plane, lies outside f's polygon (mm; 0 inside, by
// the even-odd rule over its loops).
double outside_face_mm(const ModelFace& f, const Vec3& q);

// Whether a correspondence of scene faces to model faces can be one rigid placement (beyond the thesis: the
// matcher checks normals, areas and adjacency, not where the faces lie): the matched planes agree on a
// translation within rms_mm, and (when the planes fix the translation) under it every matched scene face's
// centroid lies within outside_mm of its model face (a visible part of a face lies on the face). Among
// look-alikes with many parallel faces (polycubes) most of a search's equal-cost solutions pair a scene face
// with a parallel face a cube away.
struct PlacementCheck {
  double rms_mm = 3.0;
  double outside_mm = 5.0;
};
bool consistent_placement(const Model& model, const Mat3& R, std::span<const PlanePair> pairs,
                          const PlacementCheck& check);

// Angle of the rotation R1^T R2 (degrees).
double rotation_angle_deg(const Mat3& R1, const Mat3& R2);
// Smallest angle between R1 and R2 S over the model's symmetries S (degrees).
double rotation_angle_deg_sym(const Mat3& R1, const Mat3& R2, const Model& model);

// The equivalent pose (R S, t + R (I - S) center) closest to the identity rotation: a deterministic
// representative of a symmetric object's pose.
void canonical_pose(const Model& model, Mat3& R, Vec3& t);

// Rotation matrix nearest to M (SVD projection onto SO(3)).
Mat3 nearest_rotation(const Mat3& M);

}  // namespace fs::host::rec
