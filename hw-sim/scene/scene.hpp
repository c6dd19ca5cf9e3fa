#pragma once
// The simulated world: polyhedra with poses on a table, seen by the scanner of a ScannerCalibration.
//
// Scene JSON (all lengths in millimetres, world frame of common/calibration.hpp: table z = 0, z up):
//   {
//     "objects": [ {"model": "meshes/cube.off",          // path relative to the scene file, or a bare name
//                                                        // "cube" = meshes/cube.off next to the scene file
//                   "scale": 1.0,                        // optional uniform scale applied to the mesh first
//                   "rotation": [[1,0,0],[0,1,0],[0,0,1]] // or "quaternion": [w, x, y, z]; default identity
//                   "translation": [x, y, z]} ],         // x_world = R (scale x_model) + t
//     "table": {"normal": [0,0,1], "d": 0} | false,      // optional; default z = 0; false = no table
//     "scanner": {"steps": 500, "first_step": 0,          // optional overrides of bench_default(steps)
//                 "camera": {"width", "height", "fx", "fy", "cx", "cy", "k1", "k2", "k3", "p1", "p2",
//                            "rotation": 3x3 R_world_cam, "position": [x,y,z]},
//                 "laser": {"axis_point", "axis_dir", "normal_at_zero", "optical_gain",
//                           "mirror_angle_at_step0", "rad_per_step"}}
//   }
// Errors are fs::Error naming the file and the JSON field, e.g. "s.json: objects[1].rotation: not a
// rotation".
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/calibration.hpp"
#include "common/mesh.hpp"

namespace fs::sim {

// One planar polygon of an object, in world coordinates, with its outward normal.
struct WorldFace {
  std::vector<Vec3> polygon;
  Plane plane;  // n points out of the object
  double area = 0.0;
};

struct SceneObject {
  std::string name;             // mesh name (file stem)
  std::filesystem::path model;  // resolved mesh path
  Mesh mesh;                    // as read (model frame)
  Mat3 rotation = Mat3::Identity();
  Vec3 translation = Vec3::Zero();
  double scale = 1.0;
  std::vector<WorldFace> faces;  // faces[i] = mesh.faces[i] posed in the world (face id = i)
  Eigen::AlignedBox3d bounds;    // world bounding box
};

struct Scene {
  ScannerCalibration calibration = ScannerCalibration::bench_default();
  bool has_table = true;
  std::vector<SceneObject> objects;
  std::string source;  // file name for messages
};

// Loads a scene file; meshes are read with fs::read_mesh relative to the file's folder.
Scene load_scene(const std::filesystem::path& path);
// Parses an already-read JSON document; `base_dir` resolves model paths, `source` names it in errors.
Scene parse_scene(const nlohmann::json& doc, const std::filesystem::path& base_dir,
                  const std::string& source);

// Changes the number of galvo steps while keeping the sweep (the first and last step's mirror angles): fewer
// steps make cheaper ground-truth grids for tests.
void resample_sweep(ScannerCalibration& calibration, std::uint32_t steps);

// Adds an object (mesh in model frame) to a scene programmatically; computes its world faces and bounds.
// Throws fs::Error if the mesh is degenerate (a face without area).
void add_object(Scene& scene, Mesh mesh, const Mat3& rotation, const Vec3& translation, double scale = 1.0);

}  // namespace fs::sim
