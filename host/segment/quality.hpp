#pragma once
// Segmentation quality measures.
//  * Hoover et al. 1996 ("An experimental comparison of range image segmentation algorithms"): correct
//    detection, over-, under-segmentation, missed and noise regions at tolerance T (0.5 < T <= 1), plus the
//    normal angle error of each correctly detected region against a ground-truth normal.
//  * Object spanning for data with per-point object labels (mOSD): the share of region area whose region
//    lies (>= purity) within one labelled object.
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <vector>

#include "common/calibration.hpp"
#include "host/segment/segmentation.hpp"

namespace fs::host::seg {

enum class HooverClass { Correct, Over, Under, Missed, Noise };

struct HooverMapping {
  HooverClass cls = HooverClass::Missed;
  std::vector<std::int32_t> gt;       // ground-truth labels involved
  std::vector<std::int32_t> machine;  // machine region ids involved
  double angle_error_deg = -1.0;      // Correct only, when a ground-truth normal is known
};

struct HooverResult {
  int gt_regions = 0, machine_regions = 0;
  int correct = 0, over = 0, under = 0, missed = 0, noise = 0;
  double mean_angle_error_deg = 0.0, max_angle_error_deg = 0.0;
  std::vector<HooverMapping> mappings;
  // ground-truth label -> class (Missed when in no mapping)
  std::map<std::int32_t, HooverClass> gt_class;
  std::map<std::int32_t, std::int32_t> gt_correct_region;  // for Correct ones: the machine region
};

// gt: ground-truth label per cell (< 0 = not a region, ignored). The machine regions are the known regions
// of `seg` (unknown regions and NIL cells belong to no machine region). gt_normal(label) may give the true
// normal (any sign) for the angle error.
HooverResult hoover_compare(std::span<const std::int32_t> gt, const Segmentation& seg, double tolerance = 0.8,
                            const std::function<std::optional<Vec3>(std::int32_t)>& gt_normal = {});

struct ObjectSpan {
  double total_area = 0.0;  // mm^2 of known regions with at least one labelled cell
  double pure_area = 0.0;   // ... of those whose cells are >= purity within one object
  int regions = 0, pure_regions = 0;
  double pure_fraction() const { return total_area > 0 ? pure_area / total_area : 1.0; }
};

// object: object id per cell (< 0 = unlabelled, ignored).
ObjectSpan object_span(std::span<const std::int32_t> object, const Segmentation& seg, double purity = 0.95);

// mOSD label -> object id: 0 -> -1 (invalid), 1..9 -> 0 (table), >= 10 -> label / 10.
inline std::int32_t mosd_object(std::int32_t label) {
  if (label <= 0) return -1;
  if (label < 10) return 0;
  return label / 10;
}

const char* to_string(HooverClass c);

}  // namespace fs::host::seg
