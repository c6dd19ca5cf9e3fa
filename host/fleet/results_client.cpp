#include "host/fleet/results_client.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/error.hpp"
#include "host/fleet/ids.hpp"

namespace fs::host::fleet {

ResultsReader::ResultsReader(NatsConnection& connection, Source source, const std::string& scanner_id)
    : connection_(connection) {
  const bool dead = source == Source::Dead;
  const char* stream = dead ? kDeadStream : kResultsStream;
  if (!scanner_id.empty()) check_scanner_id(scanner_id);
  const std::string subject = scanner_id.empty()
                                  ? std::string(dead ? kDeadPrefix : kResultsPrefix) + ">"
                                  : (dead ? dead_subject(scanner_id) : results_subject(scanner_id));
  jsStreamInfo* si = nullptr;
  jsErrCode err = static_cast<jsErrCode>(0);
  natsStatus st = js_GetStreamInfo(&si, connection.js(), stream, nullptr, &err);
  if (st != NATS_OK) throw_nats(st, fmt::format("NATS stream {}", stream), err);
  stored_at_start_ = si->State.Msgs;
  jsStreamInfo_Destroy(si);
  jsSubOptions so;
  jsSubOptions_Init(&so);
  so.Stream = stream;
  so.Ordered = true;
  so.Config.DeliverPolicy = js_DeliverAll;
  st = js_SubscribeSync(&sub_, connection.js(), subject.c_str(), nullptr, &so, &err);
  if (st != NATS_OK) throw_nats(st, fmt::format("read {} ({})", stream, subject), err);
}

ResultsReader::~ResultsReader() { connection_.end_subscription(sub_); }

std::optional<FleetResult> ResultsReader::next(std::int64_t timeout_ms) {
  natsMsg* m = nullptr;
  const natsStatus st = natsSubscription_NextMsg(&m, sub_, timeout_ms);
  if (st == NATS_TIMEOUT) return std::nullopt;
  if (st != NATS_OK) throw_nats(st, "read results");
  FleetResult r;
  r.subject = natsMsg_GetSubject(m);
  r.scan_id = nats_header(m, kHeaderScanId);
  r.scanner_id = nats_header(m, kHeaderScanner);
  r.reason = nats_header(m, kHeaderReason);
  r.body.assign(natsMsg_GetData(m), static_cast<std::size_t>(natsMsg_GetDataLength(m)));
  jsMsgMetaData* meta = nullptr;
  if (natsMsg_GetMetaData(&meta, m) == NATS_OK) {
    r.sequence = meta->Sequence.Stream;
    r.pending = meta->NumPending;
    jsMsgMetaData_Destroy(meta);
  }
  natsMsg_Destroy(m);
  return r;
}

std::string result_summary_line(const FleetResult& r, bool dead) {
  if (dead)
    return fmt::format("{} {}: DEAD ({} bytes): {}", r.scanner_id, r.scan_id, r.body.size(), r.reason);
  std::string line;
  try {
    const nlohmann::json j = nlohmann::json::parse(r.body);
    line = fmt::format("{} {}: {} object(s)", r.scanner_id, r.scan_id, j.at("objects").size());
    for (const auto& obj : j.at("objects")) {
      const auto& t = obj.at("translation");
      line += fmt::format("  {} ({:.1f}, {:.1f}, {:.1f}) {:.2f}", obj.at("model").get<std::string>(),
                          t.at(0).get<double>(), t.at(1).get<double>(), t.at(2).get<double>(),
                          obj.at("confidence").get<double>());
    }
    if (j.contains("worker")) line += fmt::format("  [worker {}]", j["worker"].value("id", std::string()));
  } catch (const std::exception& e) {
    line = fmt::format("{} {}: unreadable result ({})", r.scanner_id, r.scan_id, e.what());
  }
  return line;
}

}  // namespace fs::host::fleet
