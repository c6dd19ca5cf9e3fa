#pragma once
// `sim-frame`: renders one simulated stripe frame of a scene and writes it as PNG.
//   facetscan-fw-hil sim-frame --scene hw-sim/scenes/default.json --step 250 -o f.png [--noise 1 --seed 7
//   --mono16]
#include <CLI/CLI.hpp>

namespace fs::sim {

// Adds the subcommand `sim-frame` to `app`; its callback renders and writes the file (errors: fs::Error).
void add_sim_frame_command(CLI::App& app);

}  // namespace fs::sim
