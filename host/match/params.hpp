#pragma once
// Parameters of the inexact matcher (thesis ch. 7.3, 7.4, 7.6, 7.7): weights, thresholds, switches for the
// ten pruning conditions of table 7.6, global stops. Named presets reproduce tables 7.19, 7.28, 7.30, 7.32,
// 7.34, 7.41 and 9.3.
#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json_fwd.hpp>

namespace fs::host::match {

// The pruning conditions of table 7.6 in their order of application (9 is split into 9.1, 9.2, 9.3).
enum class Condition : int {
  kConnectivity = 0,
  kSupernode,
  kRigidity,
  kVisibility,
  kNewMatch,
  kNodeDegree,
  kNeighborMatch,
  kCostThreshold,
  kNodeSimilarity,
  kArcSimilarity,
  kRotfitSimilarity,
  kSearchDepth,
  kCount
};
inline constexpr int kConditionCount = static_cast<int>(Condition::kCount);
std::string_view condition_name(Condition c);  // "connectivity", "supernode", ... (also the JSON keys)

inline constexpr double kInf = std::numeric_limits<double>::infinity();
// The largest MatchParams::th_area_fold_deg: ArcIndex counts the neighbours within this fold in its areas.
inline constexpr double kAreaFoldMaxDeg = 20.0;

struct MatchParams {
  std::string name = "custom";
  // Cost weights (7.6.3).
  double alpha = 5e-2;   // node (area) dissimilarity
  double beta = 4e-2;    // arc attribute (border) dissimilarity
  double gamma = 1e-2;   // inserted arcs
  double delta = 1e-2;   // deleted arcs
  double epsilon = 0.9;  // rotation fitting error
  // Thresholds (7.3).
  double th_omega_deg = 20.0;  // rigidity cone opening
  // Rigidity from level-1 parents too (beyond the thesis, which predicts normals from level >= 2 parents): a
  // rotation taking the parent's reference normal r0 onto its scene normal s0 can bring a candidate's r
  // within TH_omega of its s only when |angle(r0, r) - angle(s0, s)| <= TH_omega, so other level-2 candidates
  // are removed (counted under rigidity). Off in the thesis presets.
  bool rigidity_pairs = false;
  double th_visibility_deg =
      100.0;  // max angle between a rotated reference normal and the observer (90 + eps)
  int th_maxlevel = std::numeric_limits<int>::max();
  int th_minlevel = 3;
  int th_nodedegree = 2;
  double th_cost = 1.0;  // max cost increase per added match
  double th_node = 1.0;
  // One-sided node condition (beyond the thesis, part of condition 9.1): a scene face cannot be seen larger
  // than its reference face, so a pair with area_s > th_area_ratio * area_r + th_area_slack_mm2 is removed
  // (occlusion only makes scene faces smaller). Off (infinity) in the thesis presets; the recognizer sets it.
  double th_area_ratio = kInf;
  double th_area_slack_mm2 = 0.0;
  // Beyond the thesis: a region grown over a shallow fold takes the neighbour's surface too, so the condition
  // compares with the reference face's area plus that of every neighbour whose normal is within this angle of
  // its own (degrees; 0 = the face alone). At most kAreaFoldMaxDeg, the fold ArcIndex allows for.
  double th_area_fold_deg = 0.0;
  double th_arcatt = 1.0;
  double th_rotfit = kInf;
  double degenerate_deg = 1.0;  // matched reference normals all within this of one axis = degenerate
  // Solution ranking (beyond the thesis, 7.7): solutions are ordered by cost + zeta * U, U = U_scene +
  // U_model. U_scene = area(unmatched real scene faces adjacent to the match) / (that + area(matched scene
  // faces)); U_model the same on the reference side, each unmatched face weighted by how squarely the
  // solution's rotation turns it toward the sensor (1 within 60 deg, 0 edge-on). The thesis cost is
  // normalized per level, so a small wrong match of an ambiguous part of a view can cost less than the
  // correct larger one (U_scene counts the faces it leaves next to it), and a wrong pose of a part that looks
  // like another can tie the right one (U_model counts the faces that pose would show and the scene lacks).
  // The search itself is unchanged. 0 (the thesis presets) = order by cost.
  double zeta = 0.0;
  // Switches, one per condition of table 7.6 (index = Condition).
  std::array<bool, kConditionCount> enabled{true, true, true, true, true, true,
                                            true, true, true, true, true, true};
  // Global stops (7.4).
  std::int64_t max_solutions = std::numeric_limits<std::int64_t>::max();  // TH_solutions
  std::int64_t max_states = 50000;                                        // TH_states (<= pool size)
  double max_time_ms = kInf;                                              // TH_CPU
  // Solutions (7.7.3): also report incomplete solutions below TH_minlevel ("partial").
  bool keep_partial = false;

  bool on(Condition c) const { return enabled[static_cast<std::size_t>(c)]; }
  void set(Condition c, bool v) { enabled[static_cast<std::size_t>(c)] = v; }
};

// Presets: "t7.19" (corner), "t7.28" (area + border, no orientation), "t7.30" (orientation only),
// "t7.32" (area + weighted orientation), "t7.34" (all attributes), "t7.41" (cube1), "t9.3" (recognition).
// "default" = t7.34. Throws fs::Error for an unknown name.
MatchParams preset(std::string_view name);
std::vector<std::string> preset_names();

// Parameters from JSON: {"preset": "t7.34", "alpha": ..., "th_omega_deg": ..., "conditions": {"rigidity":
// false, ...}, "max_states": ...}; keys override the preset (default "t7.34"). "inf" or null = infinity.
MatchParams params_from_json(const nlohmann::json& j, const std::string& source);
MatchParams read_params(const std::string& preset_or_file);  // a preset name or a JSON file path
nlohmann::json to_json(const MatchParams& p);

}  // namespace fs::host::match
