#include "host/fleet/scan_publisher.hpp"

#include <chrono>
#include <thread>

#include <fmt/format.h>

#include "common/error.hpp"
#include "host/fleet/ids.hpp"
#include "host/io/scan_bytes.hpp"

namespace fs::host::fleet {

ScanPublisher::ScanPublisher(NatsConnection& connection, std::string scanner_id,
                             const FleetSettings& settings)
    : connection_(connection), scanner_id_(std::move(scanner_id)) {
  check_scanner_id(scanner_id_);
  subject_ = scans_subject(scanner_id_);
  ensure_scans_stream(connection_.js(), settings);
}

PublishedScan ScanPublisher::publish(std::span<const std::uint8_t> fscan, const std::string& status,
                                     int retries, const std::string& scan_id) {
  const msg::ScanBegin begin = peek_scan_begin(fscan, "scan image");
  PublishedScan out;
  const std::string id =
      scan_id.empty() ? scan_message_id(scanner_id_, begin.scan_id, begin.start_time_ns, fscan) : scan_id;
  out.message_id = scan_id.empty() ? id : id + "-whole";
  out.scan_id = id;
  out.subject = subject_;
  out.bytes = fscan.size();
  const std::int64_t max_payload = connection_.max_payload();
  if (max_payload > 0 && static_cast<std::int64_t>(fscan.size()) > max_payload)
    throw Error(
        fmt::format("scan {}: {} bytes exceed the NATS server's max_payload of {} bytes (raise "
                    "max_payload in the server config, toolchain/deploy/nats/)",
                    out.message_id, fscan.size(), max_payload));
  const auto t0 = std::chrono::steady_clock::now();
  const NatsHeaders headers = {{kHeaderScanId, id}, {kHeaderScanner, scanner_id_}, {kHeaderStatus, status}};
  for (int attempt = 0;; ++attempt) {
    JsPublished ack;
    jsErrCode err = static_cast<jsErrCode>(0);
    const natsStatus st =
        js_publish_once(connection_.js(), subject_, out.message_id, kScansStream, fscan, headers, ack, err);
    if (st == NATS_OK) {
      out.sequence = ack.sequence;
      out.duplicate = ack.duplicate;
      break;
    }
    // A timeout or a lost connection (server restarting, cluster electing a leader): the same message id
    // again; the stream stores it once. Errors of the request itself (too large, no stream) are final.
    if (!nats_transient(st) || attempt >= retries)
      throw_nats(st, fmt::format("publish scan {} to {}", out.message_id, subject_), err);
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  out.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace fs::host::fleet
