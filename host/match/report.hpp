#pragma once
// Printing match results: the solution listing of thesis fig. 7.21 (text) and JSON (`facetscan match
// --json`).
#include <string>
#include <string_view>

#include <nlohmann/json_fwd.hpp>

#include "host/match/inexact.hpp"

namespace fs::host::match {

// Text report: per solution rank, state id (prefix.path), state number, nodes, arcs matched / inserted /
// deleted, node diss, arc attr diss, arc struct diss, rotation fit error, rotation matrix, cost, matches;
// then the statistics (states, time, solutions, best state, cost ratio, per-condition removals, stop).
std::string format_result(const MatchResult& r, std::string_view prefix, std::size_t max_solutions = 10);

// {"solutions":[{"rank","state","id","level","arcs_matched",...,"rotation":[[..]...],"matches":[[s,r],...],
//   "complete","partial","degenerate"}], "stats":{...,"removed":{"connectivity":n,...},"stop":"..."}}
nlohmann::json result_json(const MatchResult& r, std::string_view prefix, std::size_t max_solutions = 64);

}  // namespace fs::host::match
