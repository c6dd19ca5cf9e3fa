#include "host/cli/commands.hpp"

namespace fs::host::cli {

void add_recognize_commands(CLI::App& /*app*/) {}

}  // namespace fs::host::cli
