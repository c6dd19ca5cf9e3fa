#include "host/cli/commands.hpp"

namespace fs::host::cli {

void add_library_commands(CLI::App& /*app*/) {}

}  // namespace fs::host::cli
