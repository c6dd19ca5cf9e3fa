// Fuzz target: the matching-parameter JSON (`facetscan match|recognize --params FILE`,
// match::params_from_json). Any input must give parameters or fs::Error, never a crash or hang; parameters
// that parse must survive to_json -> params_from_json unchanged.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include <nlohmann/json.hpp>

#include "common/error.hpp"
#include "host/match/params.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return 0;
  try {
    const fs::host::match::MatchParams p = fs::host::match::params_from_json(j, "fuzz");
    const nlohmann::json out = fs::host::match::to_json(p);
    if (fs::host::match::to_json(fs::host::match::params_from_json(out, "fuzz round trip")) != out)
      std::abort();
  } catch (const fs::Error&) {
  }
  return 0;
}
