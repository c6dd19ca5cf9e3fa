#include "host/match/params.hpp"

#include <cmath>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "common/error.hpp"
#include "common/input_file.hpp"
#include "common/json_text.hpp"

namespace fs::host::match {

namespace {

constexpr std::array<std::string_view, kConditionCount> kNames = {
    "connectivity",    "supernode",      "rigidity",          "visibility",
    "new_match",       "node_degree",    "neighbor_match",    "cost_threshold",
    "node_similarity", "arc_similarity", "rotfit_similarity", "search_depth"};

MatchParams base(const char* name, double alpha, double beta, double gamma, double delta, double epsilon,
                 double omega, int nd, double th_cost, double th_rotfit) {
  MatchParams p;
  p.name = name;
  p.alpha = alpha;
  p.beta = beta;
  p.gamma = gamma;
  p.delta = delta;
  p.epsilon = epsilon;
  p.th_omega_deg = omega;
  p.th_nodedegree = nd;
  p.th_cost = th_cost;
  p.th_rotfit = th_rotfit;
  return p;
}

}  // namespace

std::string_view condition_name(Condition c) { return kNames[static_cast<std::size_t>(c)]; }

std::vector<std::string> preset_names() {
  return {"t7.19", "t7.28", "t7.30", "t7.32", "t7.34", "t7.41", "t9.3", "fast", "scan"};
}

MatchParams preset(std::string_view name) {
  if (name == "t7.19" || name == "corner") return base("t7.19", 5e-2, 4e-2, 1e-2, 1e-2, 0.9, 20, 2, 1, kInf);
  if (name == "t7.28") {
    // Orientation without influence: epsilon 0, TH_omega 180 deg (rigidity and visibility never prune).
    MatchParams p = base("t7.28", 5e-2, 4e-2, 1e-2, 1e-2, 0.0, 180, 2, 1, kInf);
    p.th_visibility_deg = 180.0;
    return p;
  }
  if (name == "t7.30") return base("t7.30", 0.0, 0.0, 1e-2, 1e-2, 0.9, 20, 2, 1, 1);
  if (name == "t7.32") return base("t7.32", 5e-2, 0.0, 1e-2, 1e-2, 0.9, 20, 2, 1, 1);
  if (name == "t7.34" || name == "default") return base("t7.34", 5e-2, 4e-2, 1e-2, 1e-2, 0.9, 20, 2, 1, 1);
  if (name == "t7.41" || name == "cube1") return base("t7.41", 5e-2, 1e-1, 1e-2, 1e-2, 0.9, 20, 6, 0.1, 0.01);
  if (name == "fast") {
    // Not from the thesis: t7.34 weights with the tighter thresholds of t7.41 (TH_cost 0.1, TH_rotfit 0.01),
    // TH_omega 10 deg, a 5000-state budget and the first solution only (TH_solutions = 1): for libraries.
    MatchParams p = base("fast", 5e-2, 4e-2, 1e-2, 1e-2, 0.9, 10, 2, 0.1, 0.01);
    p.max_solutions = 1;
    p.max_states = 5000;
    return p;
  }
  if (name == "scan") {
    // For scanned scenes: t7.34 (all attributes) with solutions ranked by cost + zeta * unexplained neighbour
    // area (params.hpp), rotation-fit increments <= 0.005 (a matched normal off by ~6 deg at most; t7.34: 1,
    // no limit), TH_omega 10 deg with the rigidity test from level-1 parents too (normals of scanned planes
    // err by a few degrees at most, not 20), the one-sided area condition (a face is never seen larger
    // than 1.3x + 30 mm2, the face counted with its neighbours across folds of up to 15 deg, which region
    // growing follows) and a 10000-state budget (a search of a many-faced reference with congruent faces
    // can otherwise spend 50000 states before its first leaf).
    MatchParams p = base("scan", 5e-2, 4e-2, 1e-2, 1e-2, 0.9, 10, 2, 1, 0.005);
    p.zeta = 0.1;
    p.rigidity_pairs = true;
    p.th_area_ratio = 1.3;
    p.th_area_slack_mm2 = 30.0;
    p.th_area_fold_deg = 15.0;
    p.max_states = 10000;
    return p;
  }
  if (name == "t9.3") return base("t9.3", 0.0, 0.0, 1e-2, 1e-2, 0.8, 20, 6, 0.1, 1);
  throw Error("unknown match parameter preset '" + std::string(name) +
              "' (known: t7.19 t7.28 t7.30 t7.32 t7.34 "
              "t7.41 t9.3 fast scan default)");
}

MatchParams params_from_json(const nlohmann::json& j, const std::string& source) {
  if (!j.is_object()) throw Error(source + ": expected a JSON object of match parameters");
  MatchParams p = preset("t7.34");
  if (auto it = j.find("preset"); it != j.end()) {
    if (!it->is_string()) throw Error(source + ": preset: expected a string");
    p = preset(it->get<std::string>());
  }
  auto num = [&](const nlohmann::json& v, const std::string& key) -> double {
    if (v.is_null() || (v.is_string() && v.get<std::string>() == "inf")) return kInf;
    if (!v.is_number()) throw Error(source + ": " + key + ": expected a number, \"inf\" or null");
    const double d = v.get<double>();
    if (std::isnan(d)) throw Error(source + ": " + key + ": not a number");
    return d;
  };
  auto integer = [&](const nlohmann::json& v, const std::string& key, std::int64_t lo, std::int64_t hi) {
    const double d = num(v, key);
    if (std::isinf(d) && d > 0) return hi;
    if (d != std::floor(d) || d < static_cast<double>(lo) || d > static_cast<double>(hi))
      throw Error(source + ": " + key + ": expected an integer in [" + std::to_string(lo) + ", " +
                  std::to_string(hi) + "]");
    return static_cast<std::int64_t>(d);
  };
  auto nonneg = [&](const nlohmann::json& v, const std::string& key) {
    const double d = num(v, key);
    if (d < 0) throw Error(source + ": " + key + ": must be >= 0");
    return d;
  };
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string& k = it.key();
    const auto& v = it.value();
    if (k == "preset" || k == "name") {
      if (k == "name" && v.is_string()) p.name = v.get<std::string>();
    } else if (k == "alpha")
      p.alpha = nonneg(v, k);
    else if (k == "beta")
      p.beta = nonneg(v, k);
    else if (k == "gamma")
      p.gamma = nonneg(v, k);
    else if (k == "delta")
      p.delta = nonneg(v, k);
    else if (k == "epsilon")
      p.epsilon = nonneg(v, k);
    else if (k == "th_omega_deg")
      p.th_omega_deg = nonneg(v, k);
    else if (k == "th_visibility_deg")
      p.th_visibility_deg = nonneg(v, k);
    else if (k == "th_maxlevel")
      p.th_maxlevel = static_cast<int>(integer(v, k, 1, std::numeric_limits<int>::max()));
    else if (k == "th_minlevel")
      p.th_minlevel = static_cast<int>(integer(v, k, 1, std::numeric_limits<int>::max()));
    else if (k == "th_nodedegree")
      p.th_nodedegree = static_cast<int>(integer(v, k, 0, std::numeric_limits<int>::max()));
    else if (k == "th_cost")
      p.th_cost = num(v, k);
    else if (k == "th_node")
      p.th_node = num(v, k);
    else if (k == "th_area_ratio")
      p.th_area_ratio = num(v, k);
    else if (k == "th_area_slack_mm2")
      p.th_area_slack_mm2 = num(v, k);
    else if (k == "th_area_fold_deg") {
      p.th_area_fold_deg = nonneg(v, k);
      if (p.th_area_fold_deg > kAreaFoldMaxDeg)
        throw Error(source + ": " + k + ": must be <= 20 (match::kAreaFoldMaxDeg, the arc index's fold)");
      static_assert(kAreaFoldMaxDeg == 20.0, "the message above names it");
    } else if (k == "th_arcatt")
      p.th_arcatt = num(v, k);
    else if (k == "th_rotfit")
      p.th_rotfit = num(v, k);
    else if (k == "degenerate_deg")
      p.degenerate_deg = nonneg(v, k);
    else if (k == "zeta")
      p.zeta = nonneg(v, k);
    else if (k == "max_solutions")
      p.max_solutions = integer(v, k, 1, std::numeric_limits<std::int64_t>::max());
    else if (k == "max_states")
      p.max_states = integer(v, k, 1, std::numeric_limits<std::int64_t>::max());
    else if (k == "max_time_ms")
      p.max_time_ms = nonneg(v, k);
    else if (k == "rigidity_pairs") {
      if (!v.is_boolean()) throw Error(source + ": rigidity_pairs: expected true or false");
      p.rigidity_pairs = v.get<bool>();
    } else if (k == "keep_partial") {
      if (!v.is_boolean()) throw Error(source + ": keep_partial: expected true or false");
      p.keep_partial = v.get<bool>();
    } else if (k == "conditions") {
      if (!v.is_object()) throw Error(source + ": conditions: expected an object of name: true|false");
      for (auto c = v.begin(); c != v.end(); ++c) {
        int idx = -1;
        for (int i = 0; i < kConditionCount; ++i)
          if (kNames[static_cast<std::size_t>(i)] == c.key()) idx = i;
        if (idx < 0) throw Error(source + ": conditions." + c.key() + ": unknown condition");
        if (!c.value().is_boolean())
          throw Error(source + ": conditions." + c.key() + ": expected true or false");
        p.enabled[static_cast<std::size_t>(idx)] = c.value().get<bool>();
      }
    } else {
      throw Error(source + ": " + k + ": unknown match parameter");
    }
  }
  return p;
}

MatchParams read_params(const std::string& preset_or_file) {
  if (!std::filesystem::exists(preset_or_file)) return preset(preset_or_file);
  const std::string text = read_input_file(preset_or_file, kMaxConfigFileBytes, "match parameter file");
  return params_from_json(parse_json_text(text, preset_or_file), preset_or_file);
}

nlohmann::json to_json(const MatchParams& p) {
  auto num = [](double d) -> nlohmann::json {
    if (std::isinf(d)) return "inf";
    return d;
  };
  nlohmann::json j = {{"name", p.name},
                      {"alpha", p.alpha},
                      {"beta", p.beta},
                      {"gamma", p.gamma},
                      {"delta", p.delta},
                      {"epsilon", p.epsilon},
                      {"th_omega_deg", p.th_omega_deg},
                      {"th_visibility_deg", p.th_visibility_deg},
                      {"th_minlevel", p.th_minlevel},
                      {"th_nodedegree", p.th_nodedegree},
                      {"th_cost", num(p.th_cost)},
                      {"th_node", num(p.th_node)},
                      {"th_area_ratio", num(p.th_area_ratio)},
                      {"th_area_slack_mm2", num(p.th_area_slack_mm2)},
                      {"th_area_fold_deg", p.th_area_fold_deg},
                      {"th_arcatt", num(p.th_arcatt)},
                      {"th_rotfit", num(p.th_rotfit)},
                      {"degenerate_deg", p.degenerate_deg},
                      {"max_states", p.max_states},
                      {"max_time_ms", num(p.max_time_ms)},
                      {"keep_partial", p.keep_partial},
                      {"zeta", p.zeta},
                      {"rigidity_pairs", p.rigidity_pairs}};
  j["th_maxlevel"] = p.th_maxlevel == std::numeric_limits<int>::max() ? nlohmann::json("inf")
                                                                      : nlohmann::json(p.th_maxlevel);
  j["max_solutions"] = p.max_solutions == std::numeric_limits<std::int64_t>::max()
                           ? nlohmann::json("inf")
                           : nlohmann::json(p.max_solutions);
  nlohmann::json c = nlohmann::json::object();
  for (int i = 0; i < kConditionCount; ++i)
    c[std::string(kNames[static_cast<std::size_t>(i)])] = p.enabled[static_cast<std::size_t>(i)];
  j["conditions"] = c;
  return j;
}

}  // namespace fs::host::match
