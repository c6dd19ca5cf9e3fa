// facetscan: the host program (recognition of planar-faced parts from laser-stripe scans and point clouds).
#include <cstdio>
#include <exception>

#include <CLI/CLI.hpp>

#include "common/error.hpp"
#include "facetscan_version.hpp"
#include "host/cli/commands.hpp"

int main(int argc, char** argv) {
  CLI::App app{"facetscan: recognize planar-faced parts (polyhedra) in laser-stripe scans and point clouds"};
  app.set_version_flag("--version", std::string("facetscan ") + fs::kVersion);
  app.require_subcommand(1);
  fs::host::cli::add_io_commands(app);
  fs::host::cli::add_graph_commands(app);
  fs::host::cli::add_library_commands(app);
  fs::host::cli::add_match_commands(app);
  fs::host::cli::add_recognize_commands(app);
  fs::host::cli::add_fleet_commands(app);
  if (app.get_subcommands({}).empty()) app.require_subcommand(0);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const fs::Error& e) {
    std::fprintf(stderr, "facetscan: error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "facetscan: internal error: %s\n", e.what());
    return 2;
  }
  return 0;
}
