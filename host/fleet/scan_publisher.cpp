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
  for (int attempt = 0;; ++attempt) {
    natsMsg* m = nullptr;
    natsStatus st = natsMsg_Create(&m, subject_.c_str(), nullptr, reinterpret_cast<const char*>(fscan.data()),
                                   static_cast<int>(fscan.size()));
    if (st != NATS_OK) throw_nats(st, "scan message");
    natsMsgHeader_Set(m, kHeaderScanId, id.c_str());
    natsMsgHeader_Set(m, kHeaderScanner, scanner_id_.c_str());
    natsMsgHeader_Set(m, kHeaderStatus, status.c_str());
    jsPubOptions po;
    jsPubOptions_Init(&po);
    po.MsgId = out.message_id.c_str();
    po.ExpectStream = kScansStream;
    jsPubAck* ack = nullptr;
    jsErrCode err = static_cast<jsErrCode>(0);
    st = js_PublishMsg(&ack, connection_.js(), m, &po, &err);
    natsMsg_Destroy(m);
    if (st == NATS_OK) {
      out.sequence = ack->Sequence;
      out.duplicate = ack->Duplicate;
      jsPubAck_Destroy(ack);
      break;
    }
    // A timeout or a lost connection (server restarting, cluster electing a leader): the same message id
    // again; the stream stores it once. Errors of the request itself (too large, no stream) are final.
    const bool transient =
        st == NATS_TIMEOUT || st == NATS_CONNECTION_DISCONNECTED || st == NATS_NO_RESPONDERS;
    if (!transient || attempt >= retries)
      throw_nats(st, fmt::format("publish scan {} to {}", out.message_id, subject_), err);
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  out.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace fs::host::fleet
