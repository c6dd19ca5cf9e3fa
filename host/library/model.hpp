#pragma once
// Reference models (thesis ch. 4): a polyhedral mesh turned into planar faces, a PFRG and the data later
// stages need (face polygons for low-level verification, the rotation symmetry group, totals).
#include <cstddef>
#include <string>
#include <vector>

#include "common/calibration.hpp"
#include "common/mesh.hpp"
#include "host/pfrg/pfrg.hpp"

namespace fs::host {

// One planar face of a model (= PFRG node with id = index into Model::faces).
struct ModelFace {
  Vec3 normal = Vec3::UnitZ();   // unit, pointing out of the object
  double offset = 0.0;           // plane: normal . x = offset (mm)
  double area = 0.0;             // mm^2
  Vec3 centroid = Vec3::Zero();  // area centroid (mm)
  double perimeter = 0.0;        // total length of all loops (mm)
  // Closed 3D boundary loops (first vertex not repeated). Counter-clockwise seen from outside (i.e. around
  // +normal) for outer boundaries, clockwise for holes. Collinear vertices are removed.
  std::vector<std::vector<Vec3>> loops;
};

struct BuildOptions {
  double scale = 1.0;                // multiply all coordinates (e.g. file in metres -> mm: 1000)
  double merge_angle_deg = 0.5;      // adjacent facets whose normals differ less than this are one face
  double weld_tolerance = 1e-7;      // vertices closer than this * bounding-box diagonal are one vertex
  bool allow_open = false;           // accept meshes with boundary edges (Model::open is then set)
  double symmetry_tolerance = 5e-3;  // relative (lengths / bounding radius, areas / largest face, angles rad)
};

struct Model {
  std::string name;
  // Nodes: id = face index, area, unit outward normal, offset, centroid (has_plane = true). Arcs: faces that
  // share edges, border = total shared edge length. No supernode (see views.hpp for scene-like views).
  Pfrg graph;
  std::vector<ModelFace> faces;
  // The rotation group of the object about `center`: every S maps the model onto itself,
  // center + S (x - center). Includes the identity (first). A pose (R, t) of the model is equivalent to
  // (R S, t + R (I - S) center) for every S.
  std::vector<Mat3> symmetries;
  Vec3 center = Vec3::Zero();    // volume centroid (area centroid of the surface when open)
  double total_area = 0.0;       // mm^2
  double volume = 0.0;           // mm^3 (0 when open)
  double bounding_radius = 0.0;  // max distance of a vertex from center (mm)
  bool open = false;             // built from an open mesh: faces may be missing

  std::size_t face_count() const { return faces.size(); }
  std::size_t arc_count() const { return graph.arcs.size(); }
  std::size_t symmetry_order() const { return symmetries.size(); }
  double total_border() const;  // sum of arc border lengths (mm)
};

// Builds a model from a polygon mesh (any winding, triangulated or not). Coplanar adjacent facets are merged
// into faces, the winding is made consistent and outward. Throws fs::Error naming mesh.name for empty,
// degenerate, open (unless allow_open), non-manifold or non-orientable meshes.
// Errors name `source` (the mesh file's path), or the mesh's name when it is empty.
Model build_model(const Mesh& mesh, const BuildOptions& options = {}, const std::string& source = {});

// Fills graph, center, totals and (when with_symmetries) symmetries from name + faces + arcs (used by
// build_model, the polycube generator and the library reader). `arcs` are (a, b, border) with a < b.
void finish_model(Model& model, std::vector<PfrgArc> arcs, const BuildOptions& options = {},
                  bool with_symmetries = true);

// The rotation group of a model computed from its faces (normals, areas, centroids, perimeters) and
// adjacency; identity first.
std::vector<Mat3> compute_symmetries(const Model& model, double relative_tolerance = 5e-3);

// For every face, the lowest face index its orbit under model.symmetries holds (the face itself when the
// model has no symmetry): faces with rep[f] == f are one face per orbit. A symmetry that maps a face onto no
// face within relative_tolerance (normal, centroid / bounding radius, area / largest face) is not counted for
// it.
std::vector<int> face_orbit_representatives(const Model& model, double relative_tolerance = 1e-2);

}  // namespace fs::host
