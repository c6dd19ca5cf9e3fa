#include "host/fleet/nats_connection.hpp"

#include <cstdlib>

#include <fmt/format.h>

#include "common/error.hpp"

namespace fs::host::fleet {

std::vector<ServerUrl> parse_server_urls(const std::string& urls) {
  std::vector<ServerUrl> out;
  std::size_t pos = 0;
  while (pos <= urls.size()) {
    std::size_t comma = urls.find(',', pos);
    if (comma == std::string::npos) comma = urls.size();
    std::string u = urls.substr(pos, comma - pos);
    pos = comma + 1;
    while (!u.empty() && u.front() == ' ') u.erase(u.begin());
    while (!u.empty() && u.back() == ' ') u.pop_back();
    if (u.empty()) continue;
    ServerUrl s;
    s.raw = u;
    s.scheme = "nats";
    const std::size_t sep = u.find("://");
    if (sep != std::string::npos) {
      s.scheme = u.substr(0, sep);
      u = u.substr(sep + 3);
    }
    if (s.scheme != "nats" && s.scheme != "tls")
      throw Error(fmt::format("NATS URL '{}': scheme must be nats:// or tls://", u));
    const std::size_t at = u.rfind('@');
    if (at != std::string::npos) u = u.substr(at + 1);
    std::string port;
    if (!u.empty() && u.front() == '[') {
      const std::size_t close = u.find(']');
      if (close == std::string::npos) throw Error(fmt::format("NATS URL '{}': unclosed '['", u));
      s.host = u.substr(1, close - 1);
      if (close + 1 < u.size() && u[close + 1] == ':') port = u.substr(close + 2);
    } else {
      const std::size_t colon = u.find(':');
      s.host = u.substr(0, colon);
      if (colon != std::string::npos) port = u.substr(colon + 1);
    }
    while (!port.empty() && port.back() == '/') port.pop_back();
    if (!port.empty()) {
      char* end = nullptr;
      const long p = std::strtol(port.c_str(), &end, 10);
      if (*end != '\0' || p <= 0 || p > 65535) throw Error(fmt::format("NATS URL '{}': bad port", u));
      s.port = static_cast<int>(p);
    }
    if (s.host.empty()) throw Error(fmt::format("NATS URL '{}': no host", u));
    out.push_back(std::move(s));
  }
  if (out.empty()) throw Error("NATS URL is empty");
  return out;
}

bool is_loopback_host(const std::string& host) {
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

void check_transport_policy(const std::string& urls, bool insecure) {
  for (const ServerUrl& s : parse_server_urls(urls)) {
    if (s.scheme == "tls" || is_loopback_host(s.host) || insecure) continue;
    throw Error(fmt::format(
        "refusing plain-text NATS to {}:{} (not a loopback address): use tls://{}:{} with --nats-ca, or "
        "--insecure on a trusted network",
        s.host, s.port, s.host, s.port));
  }
}

std::string nats_error_text(natsStatus s, const std::string& what, jsErrCode err) {
  std::string t = fmt::format("{}: {}", what, natsStatus_GetText(s));
  const char* last = nats_GetLastError(nullptr);
  if (last != nullptr && *last != '\0' && std::string(last) != natsStatus_GetText(s))
    t += fmt::format(" ({})", last);
  if (static_cast<int>(err) != 0) t += fmt::format(" [JetStream error {}]", static_cast<int>(err));
  return t;
}

void throw_nats(natsStatus s, const std::string& what, jsErrCode err) {
  throw Error(nats_error_text(s, what, err));
}

bool nats_transient(natsStatus st) {
  return st == NATS_TIMEOUT || st == NATS_CONNECTION_DISCONNECTED || st == NATS_NO_RESPONDERS;
}

std::string nats_header(natsMsg* m, const char* key) {
  const char* v = nullptr;
  if (natsMsgHeader_Get(m, key, &v) != NATS_OK || v == nullptr) return {};
  return v;
}

natsStatus js_publish_once(jsCtx* js, const std::string& subject, const std::string& msg_id,
                           const char* stream, std::span<const std::uint8_t> body, const NatsHeaders& headers,
                           JsPublished& out, jsErrCode& err) {
  natsMsg* m = nullptr;
  natsStatus st = natsMsg_Create(&m, subject.c_str(), nullptr, reinterpret_cast<const char*>(body.data()),
                                 static_cast<int>(body.size()));
  if (st != NATS_OK) throw_nats(st, "message for " + subject);
  for (const auto& [k, v] : headers)
    if (!v.empty()) natsMsgHeader_Set(m, k.c_str(), v.c_str());
  jsPubOptions po;
  jsPubOptions_Init(&po);
  po.MsgId = msg_id.c_str();
  po.ExpectStream = stream;
  jsPubAck* ack = nullptr;
  err = static_cast<jsErrCode>(0);
  st = js_PublishMsg(&ack, js, m, &po, &err);
  natsMsg_Destroy(m);
  if (st == NATS_OK) {
    out.sequence = ack->Sequence;
    out.duplicate = ack->Duplicate;
    jsPubAck_Destroy(ack);
  }
  return st;
}

namespace {

void check(natsStatus s, const char* what) {
  if (s != NATS_OK) throw_nats(s, what);
}

std::string env_or(const std::string& value, const char* name) {
  if (!value.empty()) return value;
  const char* v = std::getenv(name);
  return v != nullptr ? std::string(v) : std::string();
}

}  // namespace

NatsConnection::NatsConnection(const NatsOptions& options) : options_(options) {
  check_transport_policy(options.url, options.insecure);
  bool tls = false;
  std::vector<const char*> servers;
  const std::vector<ServerUrl> urls = parse_server_urls(options.url);
  for (const ServerUrl& s : urls) {
    tls = tls || s.scheme == "tls";
    servers.push_back(s.raw.c_str());
  }
  natsOptions* o = nullptr;
  check(natsOptions_Create(&o), "NATS options");
  try {
    check(natsOptions_SetServers(o, servers.data(), static_cast<int>(servers.size())),
          ("NATS URL " + options.url).c_str());
    check(natsOptions_SetNoRandomize(o, false), "NATS server order");
    if (!options.name.empty()) check(natsOptions_SetName(o, options.name.c_str()), "NATS client name");
    const std::string user = env_or(options.user, "FACETSCAN_NATS_USER");
    const std::string password = env_or(options.password, "FACETSCAN_NATS_PASSWORD");
    if (!user.empty()) check(natsOptions_SetUserInfo(o, user.c_str(), password.c_str()), "NATS user");
    if (tls || !options.ca_file.empty()) {
      check(natsOptions_SetSecure(o, true), "NATS TLS");
      if (!options.ca_file.empty())
        check(natsOptions_LoadCATrustedCertificates(o, options.ca_file.c_str()),
              ("NATS CA file " + options.ca_file).c_str());
      if (!options.cert_file.empty())
        check(natsOptions_LoadCertificatesChain(o, options.cert_file.c_str(), options.key_file.c_str()),
              ("NATS client certificate " + options.cert_file).c_str());
    }
    check(natsOptions_SetTimeout(o, options.connect_timeout_ms), "NATS connect timeout");
    check(natsOptions_SetMaxReconnect(o, -1), "NATS reconnects");
    check(natsOptions_SetReconnectWait(o, 250), "NATS reconnect wait");
    check(natsOptions_SetReconnectJitter(o, 100, 1000), "NATS reconnect jitter");
    // A scan published while the connection is down waits in the reconnect buffer (up to one 8 MB scan);
    // its publish acknowledgement then times out and the caller retries with the same message id.
    check(natsOptions_SetReconnectBufSize(o, 16 * 1024 * 1024), "NATS reconnect buffer");
    if (options.connect_in_background)
      // With a connected callback the library connects asynchronously (without one it would retry here,
      // forever, with MaxReconnect -1).
      check(natsOptions_SetRetryOnFailedConnect(
                o, true, [](natsConnection*, void*) {}, nullptr),
            "NATS connect in background");
    const natsStatus s = natsConnection_Connect(&nc_, o);
    if (s != NATS_OK && !(options.connect_in_background && s == NATS_NOT_YET_CONNECTED))
      throw_nats(s, "cannot connect to NATS at " + options.url);
    natsOptions_Destroy(o);
    o = nullptr;
    jsOptions jo;
    check(jsOptions_Init(&jo), "JetStream options");
    jo.Wait = options.js_wait_ms;
    check(natsConnection_JetStream(&js_, nc_, &jo), "JetStream context");
  } catch (...) {
    if (o != nullptr) natsOptions_Destroy(o);
    if (nc_ != nullptr) natsConnection_Destroy(nc_);
    nc_ = nullptr;
    throw;
  }
}

NatsConnection::~NatsConnection() {
  if (js_ != nullptr) jsCtx_Destroy(js_);
  if (nc_ != nullptr) {
    natsConnection_FlushTimeout(nc_, 1000);
    natsConnection_Close(nc_);  // joins the read loop
  }
  for (natsSubscription* sub : kept_) natsSubscription_Destroy(sub);
  if (nc_ != nullptr) natsConnection_Destroy(nc_);
}

void NatsConnection::end_subscription(natsSubscription* sub) {
  if (sub == nullptr) return;
  natsSubscription_Unsubscribe(sub);
  // Flushed only while connected: a flush made while the client reconnects waits for its whole timeout.
  constexpr std::int64_t kFlushMs = 2000;
  if (natsConnection_Status(nc_) == NATS_CONN_STATUS_CONNECTED &&
      natsConnection_FlushTimeout(nc_, kFlushMs) == NATS_OK) {
    natsSubscription_Destroy(sub);
    return;
  }
  std::lock_guard lock(kept_mu_);
  kept_.push_back(sub);
}

std::size_t NatsConnection::kept_subscriptions() const {
  std::lock_guard lock(kept_mu_);
  return kept_.size();
}

std::int64_t NatsConnection::max_payload() const { return natsConnection_GetMaxPayload(nc_); }

bool NatsConnection::connected() const { return natsConnection_Status(nc_) == NATS_CONN_STATUS_CONNECTED; }

std::string NatsConnection::connected_url() const {
  char buf[512] = {0};
  if (natsConnection_GetConnectedUrl(nc_, buf, sizeof buf) != NATS_OK) return {};
  return buf;
}

}  // namespace fs::host::fleet
