#include "host/fleet/streams.hpp"

#include <string>
#include <vector>

#include <fmt/format.h>

#include "common/error.hpp"
#include "host/fleet/ids.hpp"
#include "host/fleet/nats_connection.hpp"

namespace fs::host::fleet {
namespace {

struct StreamSpec {
  const char* name;
  std::string subject;
  jsRetentionPolicy retention;
  jsDiscardPolicy discard;
  std::int64_t max_bytes;
  std::int64_t max_age_s;
};

StreamSpec scans_spec(const FleetSettings& s) {
  return {
      kScansStream, std::string(kScansPrefix) + ">", js_WorkQueuePolicy, js_DiscardNew, s.scans_max_bytes, 0};
}

StreamSpec parts_spec(const FleetSettings& s) {
  return {kPartsStream,      std::string(kPartsPrefix) + ">",
          js_LimitsPolicy,   js_DiscardNew,
          s.parts_max_bytes, s.parts_max_age_s};
}

void ensure_stream(jsCtx* js, const StreamSpec& spec, const FleetSettings& s, bool create) {
  jsStreamInfo* si = nullptr;
  jsErrCode err = static_cast<jsErrCode>(0);
  natsStatus st = js_GetStreamInfo(&si, js, spec.name, nullptr, &err);
  if (st == NATS_OK) {
    std::string problem;
    const jsStreamConfig* c = si->Config;
    if (c->Retention != spec.retention) problem = "another retention policy";
    if (c->Storage != js_FileStorage) problem = "memory storage";
    bool has_subject = false;
    for (int i = 0; i < c->SubjectsLen; ++i) has_subject = has_subject || spec.subject == c->Subjects[i];
    if (!has_subject) problem = "not the subject " + spec.subject;
    jsStreamInfo_Destroy(si);
    if (!problem.empty())
      throw Error(fmt::format("NATS stream {} exists with {}: delete it or fix it (docs/fleet.md#streams)",
                              spec.name, problem));
    return;
  }
  if (err != JSStreamNotFoundErr && st != NATS_NOT_FOUND)
    throw_nats(st, fmt::format("NATS stream {}: info", spec.name), err);
  if (!create)
    throw Error(
        fmt::format("NATS stream {} is missing: run `facetscan fleet-setup` as the admin user", spec.name));
  jsStreamConfig cfg;
  jsStreamConfig_Init(&cfg);
  cfg.Name = spec.name;
  const char* subjects[] = {spec.subject.c_str()};
  cfg.Subjects = subjects;
  cfg.SubjectsLen = 1;
  cfg.Retention = spec.retention;
  cfg.Discard = spec.discard;
  cfg.Storage = js_FileStorage;
  cfg.Replicas = s.replicas;
  cfg.MaxBytes = spec.max_bytes;
  cfg.MaxAge = spec.max_age_s * std::int64_t(1000000000);
  cfg.Duplicates = s.duplicate_window_s * std::int64_t(1000000000);
  st = js_AddStream(&si, js, &cfg, nullptr, &err);
  if (st != NATS_OK) throw_nats(st, fmt::format("NATS stream {}: create", spec.name), err);
  jsStreamInfo_Destroy(si);
}

}  // namespace

void ensure_scans_stream(jsCtx* js, const FleetSettings& settings, bool create) {
  ensure_stream(js, scans_spec(settings), settings, create);
}

void ensure_parts_stream(jsCtx* js, const FleetSettings& settings, bool create) {
  ensure_stream(js, parts_spec(settings), settings, create);
}

ConsumerSettings ensure_fleet(jsCtx* js, const FleetSettings& s, bool create) {
  ensure_stream(js, scans_spec(s), s, create);
  ensure_stream(js, parts_spec(s), s, create);
  ensure_stream(js,
                {kResultsStream, std::string(kResultsPrefix) + ">", js_LimitsPolicy, js_DiscardOld,
                 s.results_max_bytes, s.results_max_age_s},
                s, create);
  ensure_stream(
      js, {kDeadStream, std::string(kDeadPrefix) + ">", js_LimitsPolicy, js_DiscardOld, s.dead_max_bytes, 0},
      s, create);

  jsConsumerInfo* ci = nullptr;
  jsErrCode err = static_cast<jsErrCode>(0);
  natsStatus st = js_GetConsumerInfo(&ci, js, kScansStream, kWorkersConsumer, nullptr, &err);
  if (st != NATS_OK) {
    if (err != JSConsumerNotFoundErr && st != NATS_NOT_FOUND)
      throw_nats(st, fmt::format("NATS consumer {}.{}: info", kScansStream, kWorkersConsumer), err);
    if (!create)
      throw Error(fmt::format("NATS consumer {}.{} is missing: run `facetscan fleet-setup` as the admin user",
                              kScansStream, kWorkersConsumer));
    jsConsumerConfig cfg;
    jsConsumerConfig_Init(&cfg);
    cfg.Durable = kWorkersConsumer;
    cfg.Description = "facetscan workers (shared pull consumer)";
    cfg.AckPolicy = js_AckExplicit;
    cfg.DeliverPolicy = js_DeliverAll;
    cfg.AckWait = s.ack_wait_ms * std::int64_t(1000000);
    cfg.MaxDeliver = s.max_deliver;
    cfg.MaxAckPending = s.max_ack_pending;
    const std::string filter = std::string(kScansPrefix) + ">";
    cfg.FilterSubject = filter.c_str();
    cfg.Replicas = s.replicas;
    st = js_AddConsumer(&ci, js, kScansStream, &cfg, nullptr, &err);
    if (st != NATS_OK)
      throw_nats(st, fmt::format("NATS consumer {}.{}: create", kScansStream, kWorkersConsumer), err);
  }
  ConsumerSettings out;
  out.ack_wait_ms = ci->Config->AckWait / 1000000;
  out.max_deliver = static_cast<int>(ci->Config->MaxDeliver);
  jsConsumerInfo_Destroy(ci);
  if (out.max_deliver <= 0)
    throw Error(fmt::format("NATS consumer {}.{} has no MaxDeliver: a failing scan would loop forever",
                            kScansStream, kWorkersConsumer));
  return out;
}

}  // namespace fs::host::fleet
