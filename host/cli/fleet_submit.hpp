#pragma once
// Publishing recorded scans to the fleet and waiting for their results: `facetscan submit` and
// `facetscan recognize --nats` (host/cli/fleet_commands.cpp; docs/fleet.md).
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "host/fleet/nats_connection.hpp"

namespace fs::host::cli {

struct SubmitCli {
  fleet::NatsOptions nats;
  std::vector<std::string> inputs;  // .fscan files or directories of them
  std::string scanner = "offline";
  bool wait = false;  // wait for every result (or dead letter) and print it
  bool quiet = false;
  double timeout_s = 0;
};

// Publishes every .fscan of the inputs (as the gateway does); with `wait`, prints each result as it arrives
// (progress bar) and throws fs::Error when some scans failed (dead-lettered) or results are missing.
void run_submit(SubmitCli& options);

// --nats URL (required when `required`), --insecure, --nats-ca, --nats-cert, --nats-key.
void add_nats_options(CLI::App* cmd, fleet::NatsOptions& options, bool required = true);

}  // namespace fs::host::cli
