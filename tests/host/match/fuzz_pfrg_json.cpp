// Fuzz target: PFRG JSON parsing + validation, then the inexact matcher on the parsed graph against itself.
// Any input must give a graph or fs::Error, never a crash or hang.
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "common/error.hpp"
#include "host/match/inexact.hpp"
#include "host/match/params.hpp"
#include "host/pfrg/pfrg.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static fs::host::match::InexactMatcher matcher(fs::host::match::MatcherLimits{2000, 8});
  const std::string text(reinterpret_cast<const char*>(data), size);
  nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return 0;
  try {
    const fs::host::Pfrg g = fs::host::pfrg_from_json(j, "fuzz");
    (void)fs::host::to_json(g).dump();
    fs::host::match::MatchParams p = fs::host::match::preset("t7.34");
    p.max_states = 2000;
    (void)matcher.match(g, g, p);
  } catch (const fs::Error&) {
  }
  return 0;
}
