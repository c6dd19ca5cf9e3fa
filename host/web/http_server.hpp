#pragma once
// The live web view's HTTP server (cpp-httplib), in its own threads beside the scanner loop:
//   GET /                          the page (assets.hpp), /static/<name> its scripts and three.js
//   GET /api/status                the scanner's state (api.hpp: status_json)
//   GET /api/scans                 the last N scans, newest first
//   GET /api/scans/ID              one scan: result, models, table, links
//   GET /api/scans/ID/points       its points (binary, api.hpp)
//   GET /api/events                Server-Sent Events: "status" (coalesced) and "scan" (a new result)
//   GET /scans/ID/files/<path>     a file of the scan's output folder (report/, result.json)
//   GET /scans/ID/recording.fscan  the recording that holds the scan
// Read-only (other methods: 405). Binds loopback by default. Bounded: `threads` requests in flight,
// `max_connections` connections open or waiting (beyond: 503), `max_event_clients` event streams (beyond:
// 503), `event_queue` events queued per stream (the oldest is dropped), `history` scans kept. publish_*() are
// called from the scanner / recognizer thread and never wait for a client (event_hub.hpp).
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <thread>

#include "host/web/api.hpp"
#include "host/web/assets.hpp"
#include "host/web/event_hub.hpp"
#include "host/web/scan_history.hpp"

namespace httplib {
class Server;
}

namespace fs::host::web {

struct WebOptions {
  std::string listen = "127.0.0.1:8080";  // ADDR:PORT; port 0 picks a free port (see port())
  int threads = 8;
  int max_connections = 64;
  int max_event_clients = 8;
  std::size_t event_queue = 64;
  std::size_t history = 16;
  int keep_alive_s = 2;
  int io_timeout_s = 5;  // read / write timeout: a client that stops reading is dropped after this
};

struct WebStats {
  std::uint64_t requests = 0, rejected_busy = 0, events_published = 0, events_dropped = 0,
                event_clients_rejected = 0;
  std::size_t event_clients = 0, history = 0, history_bytes = 0;
};

class WebServer {
 public:
  explicit WebServer(WebOptions options);
  ~WebServer();
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  // Loads the assets, binds (throws fs::Error naming the address) and serves in background threads.
  void start();
  void stop();
  std::uint16_t port() const { return port_; }
  std::string url() const;

  // Thread-safe, non-blocking.
  void publish_status(const LiveStatus& s);
  void publish_scan(std::shared_ptr<const ScanRecord> record);

  const ScanHistory& history() const { return history_; }
  WebStats stats() const;

 private:
  void routes();
  WebOptions opt_;
  std::unique_ptr<httplib::Server> svr_;
  std::map<std::string, Asset> assets_;
  ScanHistory history_;
  EventHub hub_;
  std::thread thread_;
  std::uint16_t port_ = 0;
  std::string host_;
  std::atomic<std::uint64_t> requests_{0}, rejected_busy_{0};
  std::atomic<int> connections_{0};
  std::mutex status_mutex_;
  std::string status_;  // latest status JSON
};

// `rel` (a request's decoded path below a root) as a path inside root, or nothing: empty, absolute, "." or
// ".." segments, empty segments, backslashes, NUL, '%' (double encoding), or a result outside root after
// resolving symlinks, or not a regular file.
std::optional<std::filesystem::path> resolve_under(const std::filesystem::path& root, std::string_view rel);

}  // namespace fs::host::web
