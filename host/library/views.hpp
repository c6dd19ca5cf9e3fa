#pragma once
// Scene-like partial views of a model: the PFRG an ideal range sensor would see.
#include "host/library/model.hpp"

namespace fs::host {

struct ViewOptions {
  // A face is visible when (R n) . (-view_dir) > min_cos (convex case; self-occlusion is ignored).
  double min_cos = 1e-9;
  bool supernode = true;  // add one supernode adjacent to every visible face bordering an invisible one
  int supernode_id = -1;  // -1: model.face_count() (node ids of faces are the model's face indices)
  Vec3 translation = Vec3::Zero();  // scene position: x_scene = R x_model + translation
};

// The PFRG of `model` in rotation R seen along view_dir (the direction from the sensor toward the object,
// need not be unit): visible faces as nodes (id = face index, full face area, rotated normal, plane offset
// and centroid in the scene frame), arcs between visible faces with their border lengths, and (optionally) a
// supernode whose arc border to a face is that face's border with the invisible faces. observer = -view_dir
// (unit, has_observer set).
Pfrg partial_view(const Model& model, const Mat3& R, const Vec3& view_dir, const ViewOptions& options = {});

// Indices of the faces visible in that view (ascending).
std::vector<int> visible_faces(const Model& model, const Mat3& R, const Vec3& view_dir,
                               double min_cos = 1e-9);

}  // namespace fs::host
