#pragma once
// A scanner geometry unlike the bench default (camera straight above the table, galvo mirror beside it): a
// camera seen from the front and tilted, the laser from behind, as other light-plane scanners are built. For
// benchmarks that must not be tuned to one geometry (bench_recognition --rig oblique).
//
//   Scene s = ...;  s.calibration = fs::sim::oblique_rig(240);
//   RandomScene r = fs::sim::make_oblique_scene(catalog, {.category = SceneCategory::cluttered}, seed);
//
// The camera at (0, -180, 520) looks at the table origin (tilted about 19 degrees toward +y), its image rows
// running along world x: 320 rows cover table x in about [-155, 155] mm. The galvo mirror at
// (0, 150, 480), its axis along x, sweeps the stripe over table y in [-110, 110] mm in `steps` steps (the
// first one at y = -110). No lens distortion.
#include <cstdint>

#include "common/calibration.hpp"
#include "hw-sim/scene/random_scene.hpp"

namespace fs::sim {

ScannerCalibration oblique_rig(std::uint32_t steps = 240);

// make_random_scene seen by oblique_rig(options.steps): the objects placed in x [-100, 100], y [-85, 85] mm
// (options' placement rectangle is replaced), where its sweep and image cover them whole.
RandomScene make_oblique_scene(const std::vector<CatalogEntry>& catalog, RandomSceneOptions options,
                               std::uint64_t seed);

}  // namespace fs::sim
