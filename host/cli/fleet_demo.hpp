#pragma once
// `facetscan demo --fleet N` (docs/fleet.md#demo): a whole fleet on this machine. A nats-server from the
// shipped config (toolchain/deploy/nats: TLS with certificates made by gen-certs.sh, JetStream on file
// storage, the least-privilege users), the streams (fleet-setup), M workers (`facetscan worker`), N simulated
// scanners (facetscan-fw-hil on the device twins, one shipped scene each) each streaming to its own gateway
// (`facetscan serve --nats --scanner scanner-<i>`), and the results printed as they arrive (read as the
// shop-floor user). Everything runs in OUT/fleet/ (logs, store, spools, certificates) and is stopped at the
// end.
#include <string>
#include <vector>

namespace fs::host::cli {

struct FleetDemoOptions {
  int scanners = 3;
  int workers = 2;
  int scans = 1;  // scans per scanner
  int steps = 0;  // galvo steps (0: each scene's)
  std::string out_dir = "demo-out";
  std::vector<std::string> library;  // default: the shipped scenes' meshes
  int timeout_s = 300;
  bool quiet = false;
};

// Returns 0 when every scan got its result; throws fs::Error naming what failed (a process that did not
// start, a missing result) with the tail of its log.
int run_fleet_demo(const FleetDemoOptions& options);

}  // namespace fs::host::cli
