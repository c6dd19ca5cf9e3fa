#include "host/cli/commands.hpp"

namespace fs::host::cli {

void add_match_commands(CLI::App& /*app*/) {}

}  // namespace fs::host::cli
