#pragma once
// The `cluttered` category of random_scene.hpp: a dense cluster of catalog solids, one of them on another.
//
// - clutter_min_objects .. clutter_max_objects objects (3-6), drawn like the other categories (random catalog
//   entry, random stable face, random yaw).
// - The first rests on the table at a random position in the placement rectangle. Each further table object
//   starts at the centre of a random object already on the table and moves out along a random horizontal
//   direction until its solid is a gap in [clutter_gap_min_mm, clutter_gap_max_mm] (0-2 mm) away from every
//   placed solid along their best separating axis (convex_separation.hpp). Solids, not footprints, are kept
//   apart, so an object may stand under another one's overhang.
// - `stacked_objects` (1) of them, at a random place in the order after the first, go on an object that rests
//   on the table, when a stable pose is found (else they go on the table):
//   - the supporting face faces up, tilted at most stack_max_tilt_deg (15°) from horizontal (no sliding for a
//     friction coefficient >= tan 15° = 0.27);
//   - the upper object's resting face (one of its stable faces) lies on the supporting face's plane, outward
//     normals opposite, with a random rotation about that normal;
//   - its volume centroid projects vertically stack_margin_mm (2 mm) or more inside both faces, hence inside
//     their contact polygon (it does not tip over), and the centroid of the support with everything on it
//     projects inside the support's face on the table (the support does not tip over either);
//   - it stays above the table (lowest point >= 0.5 mm), inside the placement rectangle, and apart from every
//     other solid (touching allowed: separation >= -1e-3 mm).
// - No two solids interpenetrate (separation >= -1e-3 mm for every pair); all footprints lie inside the
//   placement rectangle.
// The separating-axis test is exact for convex solids only: the catalog must hold convex meshes (the
// polyhedra of make_catalog are).
#include <vector>

#include "hw-sim/scene/prng.hpp"
#include "hw-sim/scene/random_scene.hpp"

namespace fs::sim {

// Solids at least this far apart (mm) do not interpenetrate; touching solids come out at about 0.
inline constexpr double kTouchingTolerance_mm = 1e-3;

// Places the objects of a cluttered scene into out.scene (its calibration already set) and fills out's
// per-object vectors. False when fewer than clutter_min_objects fit (the caller starts over).
bool place_cluttered(const std::vector<CatalogEntry>& catalog, const RandomSceneOptions& o, Prng& rng,
                     RandomScene& out);

}  // namespace fs::sim
