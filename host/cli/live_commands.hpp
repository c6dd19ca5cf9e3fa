#pragma once
// `facetscan serve` (recognize every scan a scanner streams) and `facetscan demo` (the hardware-in-the-loop
// demo: facetscan-fw-hil on the simulated devices streams a scan over TCP loopback to this host process).
#include <CLI/CLI.hpp>

namespace fs::host::cli {

void add_live_commands(CLI::App& app);

}  // namespace fs::host::cli
