#pragma once
// Catalog entries (random_scene.hpp) for polycubes and other closed, non-convex solids, at their size.
//
//   // meshes: e.g. the generator's polycube of each library model (host/library/polycubes.hpp,
//   // polycube_mesh_of), in the model's frame and size: no random scaling, the library was built at this
//   size auto catalog = fs::sim::make_polycube_catalog(meshes); auto s = fs::sim::make_random_scene(catalog,
//   {.category = SceneCategory::single}, seed);
//
// make_catalog's rules assume convex solids: its volume centroid sums |tetrahedra| from the vertex mean, and
// a face is stable when the centroid projects inside that one face. A polycube mesh is one quad per exposed
// unit square, so the plane a polycube rests on is made of several coplanar quads, possibly apart (two legs),
// and a face in a concavity is no resting plane at all. Here:
//  * volume and centroid are signed sums over the faces (divergence theorem), exact for any closed mesh whose
//    faces are wound consistently (either way round);
//  * a resting plane is the plane of a face that supports the solid (no vertex outside it); the solid rests
//  on
//    the convex hull of its vertices in that plane, and the plane is stable when the centroid projects inside
//    that hull by more than the margin. Each stable plane is listed once, by its lowest-numbered face (for
//    make_random_scene, whose outward_normal of that face is correct: the centroid is behind a supporting
//    plane). Resting on a hull facet that holds no face (a polycube tipped onto two edges) is not offered.
// random_scene keeps objects apart by their footprints (convex hulls of the projected vertices): a solid lies
// inside the vertical prism over its footprint, so disjoint footprints mean disjoint solids, convex or not.
#include <vector>

#include "common/mesh.hpp"
#include "hw-sim/scene/random_scene.hpp"

namespace fs::sim {

struct SolidMass {
  double volume = 0.0;  // mm^3, > 0
  Vec3 centroid = Vec3::Zero();
  bool inward = false;  // the faces are wound clockwise seen from outside
};
// Throws fs::Error naming the mesh when it has no volume.
SolidMass solid_mass(const Mesh& mesh);

// The stable resting planes of a closed mesh, one face index each (ascending). margin_mm: how far inside the
// contact hull the centroid must project.
std::vector<int> stable_resting_faces(const Mesh& mesh, const SolidMass& mass, double margin_mm = 0.5);

// Catalog entries of meshes at their size (size_mm = largest extent). Throws fs::Error naming the mesh if it
// has no volume or no stable resting plane.
std::vector<CatalogEntry> make_polycube_catalog(const std::vector<Mesh>& meshes, double margin_mm = 0.5);

}  // namespace fs::sim
