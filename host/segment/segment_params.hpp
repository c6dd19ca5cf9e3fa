#pragma once
// Parameters of the organized-grid planar segmentation (host/segment/segmenter.hpp).
// Distances in millimetres, angles in degrees, "range" = distance of a point from the viewpoint.
#include <cstdint>
#include <string_view>

namespace fs::host::seg {

struct SegmentParams {
  // Normals: cross product of the grid tangents over +-normal_span cells (one-sided at depth jumps). Along a
  // grid axis whose median neighbour spacing x normal_span exceeds normal_span_mm, the span is cut to
  // max(1, normal_span_mm / spacing) cells: a coarser sweep would otherwise reach across the edges of the
  // faces it lights at a grazing angle, only a few columns wide (0 = normal_span cells on every grid). The
  // reach stays at least noise / tan(seed_angle_deg / 2) (the scan's estimated depth noise), so that noise
  // does not turn the normals by more than half the seed angle.
  int normal_span = 2;
  double normal_span_mm = 1.6;
  // Depth continuity between grid neighbours p, q: |p - q| <= jump_abs_mm + jump_rel * range.
  double jump_abs_mm = 2.5;
  double jump_rel = 0.0;
  // Larger steps (up to jump_max_mm) still count as continuous when they make more than jump_angle_deg with
  // the viewing ray: a surface seen at a grazing angle, not a jump edge (which runs along the ray).
  double jump_angle_deg = 6.0;
  double jump_max_mm = 25.0;
  // Along each grid axis the jump threshold is at least this many times the scan's median neighbour spacing
  // along that axis (Segmentation::spacing_mm): a coarser sweep puts the points of a surface the laser meets
  // at a grazing angle farther apart than jump_abs_mm. 4 x the bench scanner's 0.62 mm at 500 steps stays
  // below jump_abs_mm; at most jump_max_mm; 0 = jump_abs_mm (+ jump_rel) alone.
  double jump_spacing_factor = 4.0;
  // Region growing: cell normal vs region normal, and point-to-plane distance to the region's plane
  // <= dist_abs_mm + dist_rel * range^2 (the range^2 term models triangulation / Kinect depth noise).
  double angle_deg = 15.0;
  double seed_angle_deg = 6.0;  // a seed's 4 neighbours must agree with its normal within this
  double dist_abs_mm = 0.3;
  double dist_rel = 0.0;  // 1/mm
  // The absolute tolerance is raised to dist_noise_factor x the scan's estimated depth noise (sigma from
  // second differences along the grid rows, always reported as Segmentation::noise_mm) when that is larger; 0
  // = fixed dist_abs_mm. The laser default 0.3 mm is 6 sigma of the bench scanner's 0.05 mm and separates
  // faces meeting at 5-6 degrees (augmented prisms). Off by default: at 4x that noise the recognition
  // benchmark found more objects with the fixed 0.3 mm (a split face costs the matcher less than a merged
  // one; docs/performance.md, segmentation).
  double dist_noise_factor = 0.0;
  // Edge refinement: unassigned cells next to a region join it when within edge_dist_factor * dist.
  double edge_dist_factor = 2.0;
  int refine_passes = 4;
  // Boundary relabelling after the merge pass: a border cell moves to the adjacent region whose plane is
  // closer (and within its distance tolerance); at most this many passes (0 = off).
  int relabel_passes = 8;
  // Merge pass: adjacent regions with normals within merge_angle_deg whose centroids lie within
  // merge_dist_factor * dist of each other's plane are one face.
  double merge_angle_deg = 4.0;
  double merge_dist_factor = 3.0;
  // A region carries attributes ("known") with at least this many cells and this area.
  std::uint32_t min_region_cells = 40;
  double min_region_area_mm2 = 5.0;
  // Grown regions smaller than this are dissolved back into unassigned cells.
  std::uint32_t min_grow_cells = 12;

  // Laser-stripe scanner (default, ~0.05 mm noise, ~0.3-0.6 mm grid spacing).
  static SegmentParams laser() { return {}; }
  // Kinect-class structured light (noise ~2.85e-6 * z^2, 640x480, ~1.7 mm spacing at 1 m).
  static SegmentParams kinect() {
    SegmentParams p;
    p.normal_span = 4;
    p.normal_span_mm = 0.0;
    p.jump_abs_mm = 0.0;
    p.jump_rel = 0.025;
    p.jump_angle_deg = 10.0;
    p.jump_max_mm = 60.0;
    p.angle_deg = 22.0;
    p.seed_angle_deg = 12.0;
    p.dist_abs_mm = 1.0;
    p.dist_rel = 6.0e-6;
    p.edge_dist_factor = 1.5;
    p.merge_angle_deg = 6.0;
    p.merge_dist_factor = 2.0;
    p.min_region_cells = 150;
    p.min_region_area_mm2 = 300.0;
    p.min_grow_cells = 40;
    // Kinect depth noise (~3 mm at 1 m) is of the order of the distance tolerance, so near a crease the
    // nearer plane is decided by noise: relabelling only moves noisy cells into small regions (more known
    // regions, less pure area on mOSD, measured by `segment_report mosd`). Off.
    p.relabel_passes = 0;
    return p;
  }
  // "laser" or "kinect"; returns false for an unknown name.
  static bool by_name(std::string_view name, SegmentParams& out) {
    if (name == "laser") {
      out = laser();
      return true;
    }
    if (name == "kinect") {
      out = kinect();
      return true;
    }
    return false;
  }
};

}  // namespace fs::host::seg
