#pragma once
// Each area of the host registers its own `facetscan` subcommands (one file per area in host/cli/).
#include <CLI/CLI.hpp>

namespace fs::host::cli {

void add_io_commands(CLI::App& app);         // export, calibrate            (host/cli/io_commands.cpp)
void add_graph_commands(CLI::App& app);      // graph                        (host/cli/graph_commands.cpp)
void add_library_commands(CLI::App& app);    // library build|list|polycubes (host/cli/library_commands.cpp)
void add_match_commands(CLI::App& app);      // isomorphisms, match          (host/cli/match_commands.cpp)
void add_recognize_commands(CLI::App& app);  // recognize, serve, demo       (host/cli/recognize_commands.cpp)
void add_fleet_commands(CLI::App& app);  // worker, results, submit, fleet-setup (host/cli/fleet_commands.cpp)

}  // namespace fs::host::cli
