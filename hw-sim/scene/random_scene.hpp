#pragma once
// Random scenes of convex polyhedra on the table, for recognition benchmarks and tests.
//
//   auto catalog = fs::sim::make_catalog(fs::sim::read_catalog_meshes(dir), {.seed = 1});  // sizes 40-80 mm
//   fs::sim::RandomScene s = fs::sim::make_random_scene(catalog, {.category = SceneCategory::occluded},
//   seed);
//   // s.scene is ready for make_ground_truth_grid; s.catalog_index[i] = catalog entry of s.scene.objects[i]
//
// Every object rests on one of its faces (a "stable" face: the projection of the volume centroid along the
// face normal falls inside the face), with a random yaw, at z >= 0 touching the table (or, in cluttered
// scenes, one of them on a face of another object). Objects never interpenetrate: in single / separated /
// occluded scenes their footprints (convex hulls of the vertices projected onto the table) are disjoint,
// which for convex solids standing on the same plane implies disjoint volumes; cluttered scenes
// (cluttered_scene.hpp) check the solids themselves (convex_separation.hpp). The whole footprint lies inside
// the placement rectangle. Everything is deterministic per (catalog, options, seed).
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "common/mesh.hpp"
#include "hw-sim/scene/scene.hpp"

namespace fs::sim {

enum class SceneCategory {
  single,     // one library object, alone
  separated,  // 2-4 library objects, footprints at least `separation_mm` apart
  occluded,   // 2-4 library objects placed touching or nearly touching (gap 0.5-3 mm): mutual occlusion
  empty,      // no library object: an empty table or a box whose proportions match no catalog solid
  cluttered,  // 3-6 library objects in a dense cluster (solid gap 0-2 mm), one of them on another when stable
};
const char* to_string(SceneCategory c);
// "single" | "separated" | "occluded" | "empty" | "cluttered"; throws fs::Error otherwise.
SceneCategory parse_scene_category(const std::string& name);

// A mesh scaled to millimetres, with its stable resting faces.
struct CatalogEntry {
  Mesh mesh;                      // scaled (mm), model frame
  double size_mm = 0.0;           // largest extent (max vertex-vertex distance)
  Vec3 centroid = Vec3::Zero();   // volume centroid
  double volume_mm3 = 0.0;        // 0 = not computed (cluttered scenes then compute it)
  std::vector<int> stable_faces;  // faces it can rest on
};

struct CatalogOptions {
  double min_size_mm = 40.0, max_size_mm = 80.0;  // largest extent drawn uniformly per mesh
  std::uint64_t seed = 1;
};

// Reads every .off file of a directory, sorted by name. Throws fs::Error if there is none.
std::vector<Mesh> read_catalog_meshes(const std::filesystem::path& dir);
// Scales each mesh to a random size and finds its stable faces. Throws fs::Error naming the mesh if it is
// degenerate (no volume) or has no stable face.
std::vector<CatalogEntry> make_catalog(const std::vector<Mesh>& meshes, const CatalogOptions& options = {});

// Volume and volume centroid of a closed convex mesh (any face winding); outward unit normal of face `f`.
double mesh_volume(const Mesh& mesh);
Vec3 volume_centroid(const Mesh& mesh);
Vec3 outward_normal(const Mesh& mesh, std::size_t face, const Vec3& interior_point);
// True when the centroid's projection along the face normal falls strictly inside face f (margin in mm).
bool is_stable_face(const Mesh& mesh, std::size_t face, const Vec3& centroid, double margin_mm = 0.0);

struct RandomSceneOptions {
  SceneCategory category = SceneCategory::single;
  int min_objects = 2, max_objects = 4;  // for separated / occluded
  double x_min = -140.0, x_max = 0.0;    // placement rectangle on the table (world mm)
  double y_min = -120.0, y_max = 120.0;
  double separation_mm = 15.0;                            // smallest footprint gap of `separated`
  double touch_gap_min_mm = 0.5, touch_gap_max_mm = 3.0;  // footprint gap of `occluded` neighbours
  // cluttered (cluttered_scene.hpp): objects, gap between solids (along their best separating axis), and
  // the stack: how many objects go on another one, how far the supporting face may tilt from horizontal,
  // how far inside both faces the upper object's centroid must project.
  int clutter_min_objects = 3, clutter_max_objects = 6;
  double clutter_gap_min_mm = 0.0, clutter_gap_max_mm = 2.0;
  int stacked_objects = 1;
  double stack_max_tilt_deg = 15.0;
  double stack_margin_mm = 2.0;
  std::uint32_t steps = 500;  // galvo steps of the scene's calibration (resample_sweep)
};

struct RandomScene {
  Scene scene;
  SceneCategory category = SceneCategory::single;
  std::vector<int> catalog_index;  // per scene object; -1 = not a catalog object (the box of `empty`)
  std::vector<int> resting_face;   // per scene object: the face it rests on (-1 for the box)
  std::vector<int> support;        // per scene object: -1 = on the table, else the object it rests on
  std::vector<int> support_face;   // per scene object: the supporting object's face under it (-1 = table)
};

RandomScene make_random_scene(const std::vector<CatalogEntry>& catalog, const RandomSceneOptions& options,
                              std::uint64_t seed);

// Footprint of a posed scene object (convex hull of its world vertices projected on z = 0,
// counter-clockwise).
std::vector<Vec2> footprint(const SceneObject& object);
// Convex hull of points on a plane (Andrew's monotone chain): counter-clockwise, no collinear points.
std::vector<Vec2> convex_hull(std::vector<Vec2> points);
// Distance between two convex polygons (0 when they overlap or touch).
double polygon_distance(const std::vector<Vec2>& a, const std::vector<Vec2>& b);

}  // namespace fs::sim
