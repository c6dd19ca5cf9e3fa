#include "host/match/report.hpp"

#include <cmath>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

namespace fs::host::match {

namespace {
nlohmann::json num(double d) {
  if (std::isnan(d)) return nullptr;
  if (std::isinf(d)) return "inf";
  return d;
}
}  // namespace

std::string format_result(const MatchResult& r, std::string_view prefix, std::size_t max_solutions) {
  std::string out;
  std::size_t k = 0;
  for (const Solution& s : r.solutions) {
    if (k++ >= max_solutions) break;
    out += fmt::format("{} {}{}{}\n", s.rank, state_id(prefix, s.path), s.complete ? "" : "  (incomplete)",
                       s.partial ? "  (partial)" : "");
    out += fmt::format("  {:>12} ; state_nb\n", s.state);
    out += fmt::format("  {:>12} ; nb of nodes matched\n", s.level);
    out += fmt::format("  {:>12} ; nb of arcs matched\n", s.arcs_matched);
    out += fmt::format("  {:>12} ; nb of sce arcs inserted\n", s.arcs_inserted);
    out += fmt::format("  {:>12} ; nb of sce arcs deleted\n", s.arcs_deleted);
    out += fmt::format("  {:>12.5E} ; node diss\n", s.node_diss);
    out += fmt::format("  {:>12.5E} ; arc attr diss\n", s.arc_attr_diss);
    out += fmt::format("  {:>12.5E} ; arc stru diss\n", s.arc_struct_diss);
    out += fmt::format("  {:>12.5E} ; rot diss{}\n", s.rotfit_error,
                       s.degenerate ? " (degenerate normal set)" : "");
    for (int i = 0; i < 3; ++i)
      out += fmt::format("  {:7.3f} {:7.3f} {:7.3f}{}\n", s.rotation(i, 0), s.rotation(i, 1),
                         s.rotation(i, 2), i == 0 ? " ; R matrix" : "");
    out += fmt::format("  {:>12.5E} ; cost\n", s.cost);
    out += fmt::format("  {:>12.5E} ; unexplained neighbour area share\n", s.unexplained);
    bool first = true;
    for (const NodeMatch& m : s.matches) {
      out += fmt::format("  {:>5} {:>5} sce / ref{}\n", m.scene, m.ref, first ? " ; matches" : "");
      first = false;
    }
  }
  const MatchStats& st = r.stats;
  out += "statistics\n";
  out += fmt::format("  number of states investigated      : {}\n", st.states_created);
  out += fmt::format("  states expanded                    : {}\n", st.states_expanded);
  out += fmt::format("  time [ms]                          : {:.3f}\n", st.time_ms);
  out += fmt::format("  best leaf found after              : {} states, {:.3f} ms\n", st.states_to_best,
                     st.time_to_best_ms);
  out += fmt::format("  number of solutions                : {}\n", st.solutions);
  out += fmt::format("  best solution at state nb          : {}\n", st.best_state);
  out += fmt::format("  cost ratio solution 2 / solution 1 : {:.4g}\n", st.cost_ratio);
  out += fmt::format("  candidate pairs examined           : {}\n", st.candidates);
  for (int c = 0; c < kConditionCount; ++c)
    out += fmt::format("  removed by {:<24}: {}\n", condition_name(static_cast<Condition>(c)),
                       st.removed[static_cast<std::size_t>(c)]);
  out += fmt::format("  removed by subset condition        : {}\n", st.subset_removed);
  out += fmt::format("  stopping condition                 : {}\n", stop_name(st.stop));
  return out;
}

nlohmann::json result_json(const MatchResult& r, std::string_view prefix, std::size_t max_solutions) {
  nlohmann::json sols = nlohmann::json::array();
  std::size_t k = 0;
  for (const Solution& s : r.solutions) {
    if (k++ >= max_solutions) break;
    nlohmann::json m = nlohmann::json::array();
    for (const NodeMatch& x : s.matches) m.push_back({x.scene, x.ref});
    nlohmann::json rot = nlohmann::json::array();
    for (int i = 0; i < 3; ++i) rot.push_back({s.rotation(i, 0), s.rotation(i, 1), s.rotation(i, 2)});
    sols.push_back({{"rank", s.rank},
                    {"id", state_id(prefix, s.path)},
                    {"state", s.state},
                    {"path", std::vector<int>(s.path.begin(), s.path.end())},
                    {"level", s.level},
                    {"arcs_matched", s.arcs_matched},
                    {"arcs_inserted", s.arcs_inserted},
                    {"arcs_deleted", s.arcs_deleted},
                    {"node_diss", s.node_diss},
                    {"arc_attr_diss", s.arc_attr_diss},
                    {"arc_struct_diss", s.arc_struct_diss},
                    {"rotfit_error", s.rotfit_error},
                    {"rotation", rot},
                    {"cost", s.cost},
                    {"unexplained", s.unexplained},
                    {"matches", m},
                    {"complete", s.complete},
                    {"partial", s.partial},
                    {"degenerate", s.degenerate}});
  }
  const MatchStats& st = r.stats;
  nlohmann::json removed = nlohmann::json::object();
  for (int c = 0; c < kConditionCount; ++c)
    removed[std::string(condition_name(static_cast<Condition>(c)))] = st.removed[static_cast<std::size_t>(c)];
  nlohmann::json stats = {{"states", st.states_created},
                          {"states_expanded", st.states_expanded},
                          {"candidates", st.candidates},
                          {"removed", removed},
                          {"leaf_solutions", st.leaf_solutions},
                          {"subset_removed", st.subset_removed},
                          {"solutions", st.solutions},
                          {"best_state", st.best_state},
                          {"cost_ratio", num(st.cost_ratio)},
                          {"stop", std::string(stop_name(st.stop))},
                          {"time_ms", st.time_ms},
                          {"states_to_best", st.states_to_best},
                          {"time_to_best_ms", st.time_to_best_ms}};
  return {{"solutions", sols}, {"stats", stats}};
}

}  // namespace fs::host::match
