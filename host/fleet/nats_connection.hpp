#pragma once
// One connection to the NATS server (or cluster) and its JetStream context, with the transport policy:
// TLS (tls://) on every non-loopback connection; plain nats:// to a non-loopback host is refused unless
// `insecure` (--insecure) is set. The connection reconnects by itself (forever, every 250 ms); JetStream
// calls made meanwhile fail with a timeout and the callers retry.
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <nats/nats.h>

namespace fs::host::fleet {

struct NatsOptions {
  std::string url;  // nats://HOST:PORT or tls://HOST:PORT, comma-separated for a cluster; user:pass@ allowed
  bool insecure = false;  // allow plain nats:// to a non-loopback host
  std::string ca_file;    // TLS: CA certificate(s) that signed the server's certificate
  std::string cert_file;  // TLS: client certificate (mutual TLS), with key_file
  std::string key_file;
  std::string user;      // empty: $FACETSCAN_NATS_USER (or the URL's user:pass@)
  std::string password;  // empty: $FACETSCAN_NATS_PASSWORD
  std::string name;      // client name shown by the server's monitoring
  int connect_timeout_ms = 5000;
  // Start while the server is unreachable (the gateway): the first connection is made in the background.
  bool connect_in_background = false;
  std::int64_t js_wait_ms = 10000;  // JetStream API / publish acknowledgement timeout
};

struct ServerUrl {
  std::string raw;     // the entry as given (with user:pass@ when present)
  std::string scheme;  // "nats" or "tls"
  std::string host;    // without brackets
  int port = 4222;
};
// Parses a URL list; throws fs::Error on a malformed entry.
std::vector<ServerUrl> parse_server_urls(const std::string& urls);
bool is_loopback_host(const std::string& host);
// Throws fs::Error when a URL names a non-loopback host without tls:// and `insecure` is not set.
void check_transport_policy(const std::string& urls, bool insecure);

// The text of a failed NATS call: "<what>: <status text> (<last error>)" and the JetStream error code.
std::string nats_error_text(natsStatus s, const std::string& what, jsErrCode err = static_cast<jsErrCode>(0));
[[noreturn]] void throw_nats(natsStatus s, const std::string& what,
                             jsErrCode err = static_cast<jsErrCode>(0));

// A failure that may pass (a timeout, the connection lost, no responder while a leader is elected): the same
// request again may succeed.
bool nats_transient(natsStatus st);

// A message header's value; "" when the message has none.
std::string nats_header(natsMsg* m, const char* key);

using NatsHeaders = std::vector<std::pair<std::string, std::string>>;
struct JsPublished {
  std::uint64_t sequence = 0;  // in the stream (of the first copy when duplicate)
  bool duplicate = false;      // the stream already held this message id: stored once
};
// One JetStream publish of `body` to `subject` under message id `msg_id` (the stream de-duplicates by it),
// expecting `stream`, with `headers` (empty values left out). Returns the status: NATS_OK fills `out`, else
// `err` holds the JetStream error. Throws fs::Error when the message cannot be made. Each caller retries as
// its role needs (gateway, streamer, worker).
natsStatus js_publish_once(jsCtx* js, const std::string& subject, const std::string& msg_id,
                           const char* stream, std::span<const std::uint8_t> body, const NatsHeaders& headers,
                           JsPublished& out, jsErrCode& err);

class NatsConnection {
 public:
  explicit NatsConnection(const NatsOptions& options);
  ~NatsConnection();
  NatsConnection(const NatsConnection&) = delete;
  NatsConnection& operator=(const NatsConnection&) = delete;

  natsConnection* get() const { return nc_; }
  jsCtx* js() const { return js_; }
  const NatsOptions& options() const { return options_; }
  // The server's max_payload (bytes): the largest message it accepts.
  std::int64_t max_payload() const;
  bool connected() const;
  std::string connected_url() const;

  // Unsubscribes and destroys `sub` (a subscription of this connection) without racing the client's read
  // loop. Debian's nats.c 3.4.1 takes an arriving message's subscription from its table, lets go of the
  // table's lock, then locks the subscription: one destroyed in between is used after it was freed, a crash
  // (nats.c#637, fixed upstream after 3.5 by nats.c#638; the `NatsSubscriptionEnd` tests provoke it). After
  // the unsubscribe a flush round trip shows the read loop past every message that arrived before it (it
  // reads them in order); when that fails (the connection is down), the subscription is kept until the
  // connection closes, when the read loop has ended. Safe from any thread.
  void end_subscription(natsSubscription* sub);
  // Subscriptions ended while the connection was down, kept until it closes.
  std::size_t kept_subscriptions() const;

 private:
  NatsOptions options_;
  natsConnection* nc_ = nullptr;
  jsCtx* js_ = nullptr;
  mutable std::mutex kept_mu_;
  std::vector<natsSubscription*> kept_;
};

}  // namespace fs::host::fleet
