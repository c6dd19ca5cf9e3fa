#pragma once
// The fleet's JetStream assets (docs/fleet.md#streams): SCANS (work queue of .fscan images, subjects
// facetscan.scans.<scanner-id>), PARTS (the parts of streamed scans), RESULTS
// (facetscan.results.<scanner-id>), DEAD (facetscan.dead.<scanner-id>: scans that failed MaxDeliver times,
// with the reason) and the durable pull consumer "workers" on SCANS that every worker shares. All on file
// storage. `facetscan fleet-setup` creates them (admin user); every role checks them at start and creates
// what is missing when its user may (a broker without accounts).
#include <cstdint>

#include <nats/nats.h>

namespace fs::host::fleet {

struct FleetSettings {
  int replicas = 1;  // stream and consumer replicas (3 on a 3-node cluster)
  // De-duplication window of SCANS and RESULTS: a scan re-sent (or a result re-published after a redelivery)
  // within it is stored once. Longer than MaxDeliver x AckWait and than the gateway's spool outlives.
  std::int64_t duplicate_window_s = 3600;
  std::int64_t scans_max_bytes = std::int64_t(4) << 30;    // SCANS full: new scans refused (not dropped)
  std::int64_t results_max_bytes = std::int64_t(1) << 30;  // RESULTS full: the oldest results go
  std::int64_t results_max_age_s = 7 * 24 * 3600;
  std::int64_t dead_max_bytes = std::int64_t(1) << 30;
  // PARTS (streamed scans): a worker purges a scan's parts once the scan is acked or terminated; parts
  // nobody purged (a stream whose SCANS message was never stored) go after max age, which is longer than any
  // backlog of SCANS should last. Full: new parts refused, the gateway sends whole scans.
  std::int64_t parts_max_bytes = std::int64_t(4) << 30;
  std::int64_t parts_max_age_s = 7 * 24 * 3600;
  // The workers' consumer.
  std::int64_t ack_wait_ms = 30000;  // a scan not acked (nor marked in progress) for this long is redelivered
  int max_deliver = 3;               // deliveries before a scan goes to DEAD
  int max_ack_pending = 256;         // scans in flight over all workers
};

// What a worker needs to know of the consumer it shares.
struct ConsumerSettings {
  std::int64_t ack_wait_ms = 0;
  int max_deliver = 0;
};

// Checks SCANS, RESULTS, DEAD, PARTS and the workers' consumer; creates what is missing when `create` (else
// throws naming what is missing and `facetscan fleet-setup`). An existing asset with another retention /
// storage / subject set is an error (it is not changed).
ConsumerSettings ensure_fleet(jsCtx* js, const FleetSettings& settings, bool create = true);

// Only what a gateway / submitter publishes into: SCANS (created when missing and `create`).
void ensure_scans_stream(jsCtx* js, const FleetSettings& settings, bool create = true);
// What a streaming gateway (serve --nats --stream) also publishes into: PARTS.
void ensure_parts_stream(jsCtx* js, const FleetSettings& settings, bool create = true);

}  // namespace fs::host::fleet
