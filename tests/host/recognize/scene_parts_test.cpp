// Connected parts of the scene graph larger than the matcher takes (match::kMaxNodes): searched in
// overlapping windows, the rest of the scene recognized as usual, the result says so.
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <string>

#include "host/library/mesh_files.hpp"
#include "host/match/node_set.hpp"
#include "host/recognize/recognizer.hpp"
#include "hw-sim/scene/ground_truth_grid.hpp"
#include "hw-sim/scene/scene.hpp"
#include "support/test_paths.hpp"

namespace {

using fs::host::rec::Recognizer;

const fs::host::Library& library() {
  static const fs::host::Library lib =
      fs::host::load_or_build_library({(fs::test::source_dir() / "hw-sim/scenes/meshes").string()});
  return lib;
}

// An egg-crate relief seen from above: tiles x tiles square facets, each tilted 25 deg along x or y in a
// checkerboard, every facet bordering its neighbours, so the scene graph is one connected part of about
// tiles^2 faces.
fs::host::OrganizedCloud egg_crate(int tiles, int per_tile, double tile_mm) {
  fs::host::OrganizedCloud c;
  const int n = tiles * per_tile;
  c.reset(static_cast<std::uint32_t>(n), static_cast<std::uint32_t>(n));
  const double slope = std::tan(25.0 * M_PI / 180.0);
  const double step = tile_mm / per_tile;
  for (int r = 0; r < n; ++r)
    for (int col = 0; col < n; ++col) {
      const double x = (col + 0.5) * step, y = (r + 0.5) * step;
      const int tx = col / per_tile, ty = r / per_tile;
      const double u = x - (tx + 0.5) * tile_mm, v = y - (ty + 0.5) * tile_mm;
      // Alternate the tilt direction and sign so that neighbouring facets differ by > 25 deg.
      const int kind = (tx + 2 * ty) % 4;
      const double z = kind == 0 ? slope * u : kind == 1 ? -slope * u : kind == 2 ? slope * v : -slope * v;
      c.points[static_cast<std::size_t>(r) * n + col] = Eigen::Vector3f(float(x), float(y), float(z));
    }
  c.viewpoint = Eigen::Vector3d(n * step / 2, n * step / 2, 600.0);
  return c;
}

TEST(SceneParts, AConnectedPartAboveTheMatcherLimitIsSearchedInWindows) {
  const fs::host::OrganizedCloud cloud = egg_crate(13, 10, 12.0);
  fs::host::rec::RecognizeParams params;
  params.threads = 2;
  params.remove_table = false;
  Recognizer rec(library(), params, cloud.points.size());
  const fs::host::rec::Recognition* r = nullptr;
  ASSERT_NO_THROW(r = &rec.recognize(cloud, nullptr));
  // The relief is one part of more faces than the matcher takes: windows, every face searched.
  EXPECT_GT(r->stats.largest_component, fs::host::match::kMaxNodes) << r->note;
  EXPECT_GE(r->stats.windows, 2);
  EXPECT_EQ(r->stats.unsearched_faces, 0);
  EXPECT_NE(r->note.find("overlapping windows"), std::string::npos) << r->note;
}

// A cube in front of a pyramid (one connected part of the scene graph) with a window cap smaller than that
// part: the windows find the objects the whole-part search finds, with the same models.
TEST(SceneParts, WindowsFindTheObjectsOfTheWholePart) {
  fs::sim::Scene scene =
      fs::sim::load_scene(fs::test::source_dir() / "hw-sim/scenes/cube-occludes-pyramid.json");
  fs::sim::resample_sweep(scene.calibration, 300);
  fs::host::OrganizedCloud cloud;
  fs::sim::make_ground_truth_grid(scene, {.depth_noise_mm = 0.05, .seed = 7}).export_to(cloud);
  const fs::Plane table = scene.calibration.table;

  fs::host::rec::RecognizeParams params;
  params.threads = 2;
  Recognizer whole(library(), params, cloud.points.size());
  const auto& a = whole.recognize(cloud, &table);
  ASSERT_EQ(a.stats.windows, 0);
  ASSERT_FALSE(a.objects.empty());
  std::multiset<int> models_a;
  int max_matched = 0;
  for (const auto& h : a.objects) {
    models_a.insert(h.model);
    max_matched = std::max(max_matched, static_cast<int>(h.matches.size()));
  }
  ASSERT_GT(a.stats.largest_component, max_matched + 1)
      << "the scene's largest part must be larger than any object for this test";

  params.max_part_faces = max_matched + 1;
  Recognizer windowed(library(), params, cloud.points.size());
  const auto& b = windowed.recognize(cloud, &table);
  EXPECT_GT(b.stats.windows, 0);
  EXPECT_EQ(b.stats.unsearched_faces, 0);
  std::multiset<int> models_b;
  for (const auto& h : b.objects) models_b.insert(h.model);
  EXPECT_EQ(models_a, models_b) << b.note;
}

}  // namespace
