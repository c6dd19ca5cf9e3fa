#include "host/web/http_server.hpp"

#include <httplib.h>
#include <sys/socket.h>

#include <cstdio>
#include <fstream>

#include <fmt/format.h>

#include "common/error.hpp"
#include "host/io/stream_server.hpp"

namespace fs::host::web {

namespace stdfs = std::filesystem;

namespace {

// Set while a worker serves a connection accepted beyond max_connections: it is answered 503 at once.
thread_local bool t_over_limit = false;

// httplib's thread pool, counting the connections open or waiting for a worker.
class CountingPool final : public httplib::TaskQueue {
 public:
  CountingPool(std::size_t threads, std::atomic<int>& open, int max_open)
      : pool_(threads), open_(open), max_open_(max_open) {}
  void enqueue(std::function<void()> fn) override {
    const bool over = open_.fetch_add(1) >= max_open_;
    pool_.enqueue([this, fn = std::move(fn), over] {
      t_over_limit = over;
      fn();
      t_over_limit = false;
      open_.fetch_sub(1);
    });
  }
  void shutdown() override { pool_.shutdown(); }

 private:
  httplib::ThreadPool pool_;
  std::atomic<int>& open_;
  int max_open_;
};

void json_reply(httplib::Response& res, const std::string& body, int status = 200) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(body, "application/json");
}

void error_reply(httplib::Response& res, int status, const std::string& why) {
  json_reply(res, nlohmann::json{{"error", why}, {"status", status}}.dump(), status);
}

// "123" -> 123; anything else (empty, sign, leading zeros beyond "0", > 18 digits) -> nothing.
std::optional<std::uint64_t> parse_id(const std::string& s) {
  if (s.empty() || s.size() > 18 || (s.size() > 1 && s[0] == '0')) return std::nullopt;
  std::uint64_t v = 0;
  for (char c : s) {
    if (c < '0' || c > '9') return std::nullopt;
    v = v * 10 + static_cast<std::uint64_t>(c - '0');
  }
  return v;
}

void send_file(httplib::Response& res, const stdfs::path& p) {
  std::error_code ec;
  const auto size = stdfs::file_size(p, ec);
  if (ec) return error_reply(res, 404, "not found");
  auto file = std::make_shared<std::ifstream>(p, std::ios::binary);
  if (!*file) return error_reply(res, 404, "not found");
  res.set_header("Cache-Control", "no-cache");
  res.set_content_provider(static_cast<std::size_t>(size), mime_type(p),
                           [file](std::size_t offset, std::size_t length, httplib::DataSink& sink) {
                             char buf[64 * 1024];
                             file->seekg(static_cast<std::streamoff>(offset));
                             const std::size_t n = std::min(length, sizeof buf);
                             file->read(buf, static_cast<std::streamsize>(n));
                             const auto got = static_cast<std::size_t>(file->gcount());
                             return got > 0 && sink.write(buf, got);
                           });
}

}  // namespace

std::optional<stdfs::path> resolve_under(const stdfs::path& root, std::string_view rel) {
  if (root.empty() || rel.empty() || rel.size() > 1024 || rel.front() == '/') return std::nullopt;
  if (rel.find_first_of(std::string_view("\\%\0", 3)) != std::string_view::npos) return std::nullopt;
  std::size_t start = 0;
  while (start <= rel.size()) {
    const std::size_t end = std::min(rel.find('/', start), rel.size());
    const std::string_view seg = rel.substr(start, end - start);
    if (seg.empty() || seg == "." || seg == "..") return std::nullopt;
    start = end + 1;
  }
  std::error_code ec;
  const stdfs::path base = stdfs::canonical(root, ec);
  if (ec) return std::nullopt;
  const stdfs::path p = stdfs::canonical(base / stdfs::path(std::string(rel)), ec);
  if (ec || !stdfs::is_regular_file(p, ec)) return std::nullopt;
  // Inside root after resolving symlinks: base is a prefix of p, component by component.
  auto b = base.begin(), q = p.begin();
  for (; b != base.end(); ++b, ++q)
    if (q == p.end() || *b != *q) return std::nullopt;
  return p;
}

WebServer::WebServer(WebOptions options)
    : opt_(std::move(options)),
      history_(opt_.history),
      hub_(static_cast<std::size_t>(std::max(1, opt_.max_event_clients)), opt_.event_queue) {
  status_ = status_json(LiveStatus{}).dump();
}

WebServer::~WebServer() { stop(); }

std::string WebServer::url() const {
  const bool v6 = host_.find(':') != std::string::npos;
  return fmt::format("http://{}{}{}:{}/", v6 ? "[" : "", host_, v6 ? "]" : "", port_);
}

void WebServer::start() {
  assets_ = load_assets();
  std::uint16_t port = 0;
  parse_listen_address(opt_.listen, host_, port);
  svr_ = std::make_unique<httplib::Server>();
  const std::size_t threads = static_cast<std::size_t>(std::max(2, opt_.threads));
  svr_->new_task_queue = [this, threads] {
    return new CountingPool(threads, connections_, std::max(1, opt_.max_connections));
  };
  svr_->set_keep_alive_timeout(opt_.keep_alive_s);
  svr_->set_keep_alive_max_count(32);
  svr_->set_read_timeout(opt_.io_timeout_s, 0);
  svr_->set_write_timeout(opt_.io_timeout_s, 0);
  svr_->set_payload_max_length(1024);  // read-only: no request bodies
  routes();
  // httplib listens with a backlog of 5: a burst of connects beyond it would wait in the kernel (SYN and data
  // retransmits, seconds) instead of being answered (503 beyond max_connections). Listen again, with room for
  // max_connections, on the socket httplib binds (it passes through the socket options).
  int listen_fd = -1;
  svr_->set_socket_options([&listen_fd](socket_t sock) {
    httplib::default_socket_options(sock);
    listen_fd = sock;
  });
  int bound = -1;
  if (port == 0)
    bound = svr_->bind_to_any_port(host_);
  else
    bound = svr_->bind_to_port(host_, port) ? port : -1;
  svr_->set_socket_options(httplib::default_socket_options);
  if (bound <= 0) throw Error("--http " + opt_.listen + ": cannot listen (address in use or not local?)");
  if (listen_fd >= 0) ::listen(listen_fd, std::max(128, 2 * opt_.max_connections));
  port_ = static_cast<std::uint16_t>(bound);
  thread_ = std::thread([this] { svr_->listen_after_bind(); });
}

void WebServer::stop() {
  hub_.close();
  if (svr_) svr_->stop();
  if (thread_.joinable()) thread_.join();
}

void WebServer::publish_status(const LiveStatus& s) {
  std::string j = status_json(s).dump();
  {
    std::lock_guard lock(status_mutex_);
    status_ = j;
  }
  hub_.publish("status", std::move(j), true);
}

void WebServer::publish_scan(std::shared_ptr<const ScanRecord> record) {
  std::string summary = record->summary_json;
  history_.add(std::move(record));
  hub_.publish("scan", std::move(summary), false);
}

WebStats WebServer::stats() const {
  WebStats s;
  s.requests = requests_.load();
  s.rejected_busy = rejected_busy_.load();
  s.events_published = hub_.published();
  s.events_dropped = hub_.dropped();
  s.event_clients_rejected = hub_.rejected();
  s.event_clients = hub_.subscribers();
  s.history = history_.size();
  s.history_bytes = history_.bytes();
  return s;
}

void WebServer::routes() {
  httplib::Server& svr = *svr_;
  svr.set_default_headers({{"X-Content-Type-Options", "nosniff"},
                           {"Referrer-Policy", "no-referrer"},
                           {"X-Frame-Options", "SAMEORIGIN"}});
  svr.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    ++requests_;
    if (t_over_limit) {
      ++rejected_busy_;
      res.set_header("Connection", "close");
      res.set_header("Retry-After", "1");
      error_reply(res, 503, "too many connections");
      return httplib::Server::HandlerResponse::Handled;
    }
    if (req.method != "GET" && req.method != "HEAD") {
      res.set_header("Allow", "GET, HEAD");
      error_reply(res, 405, "read-only API: GET only");
      return httplib::Server::HandlerResponse::Handled;
    }
    return httplib::Server::HandlerResponse::Unhandled;
  });
  svr.set_error_handler([](const httplib::Request&, httplib::Response& res) {
    if (res.body.empty()) error_reply(res, res.status, res.status == 404 ? "not found" : "error");
  });

  auto asset = [this](const std::string& name) {
    return [this, name](const httplib::Request&, httplib::Response& res) {
      const Asset& a = assets_.at(name);
      res.set_header("Cache-Control", "no-cache");
      if (name == "index.html")
        res.set_header(
            "Content-Security-Policy",
            "default-src 'self'; img-src 'self' data:; style-src 'self' 'unsafe-inline'; connect-src 'self'; "
            "frame-ancestors 'self'");
      res.set_content(a.content, a.mime);
    };
  };
  svr.Get("/", asset("index.html"));
  svr.Get("/index.html", asset("index.html"));
  for (const std::string& name : asset_names()) svr.Get("/static/" + name, asset(name));

  svr.Get("/api/status", [this](const httplib::Request&, httplib::Response& res) {
    std::string s;
    {
      std::lock_guard lock(status_mutex_);
      s = status_;
    }
    const WebStats st = stats();
    nlohmann::json j = nlohmann::json::parse(s);
    j["web"] = {{"event_clients", st.event_clients},
                {"max_event_clients", opt_.max_event_clients},
                {"history", st.history},
                {"history_capacity", history_.capacity()},
                {"history_bytes", st.history_bytes},
                {"events_dropped", st.events_dropped}};
    const auto latest = history_.latest();
    j["latest_scan"] = latest ? nlohmann::json(latest->id) : nlohmann::json(nullptr);
    json_reply(res, j.dump());
  });
  svr.Get("/api/scans", [this](const httplib::Request&, httplib::Response& res) {
    std::string body = R"({"capacity":)" + std::to_string(history_.capacity()) + R"(,"scans":[)";
    const char* sep = "";
    for (const auto& r : history_.newest_first()) {
      body += sep + r->summary_json;
      sep = ",";
    }
    json_reply(res, body + "]}");
  });
  auto with_record = [this](auto f) {
    return [this, f](const httplib::Request& req, httplib::Response& res) {
      const auto id = parse_id(req.matches[1]);
      if (!id) return error_reply(res, 400, "bad scan id");
      const auto rec = history_.find(*id);
      if (!rec)
        return error_reply(
            res, 404,
            "no such scan (the history keeps the last " + std::to_string(history_.capacity()) + ")");
      f(*rec, req, res);
    };
  };
  svr.Get(R"(/api/scans/([^/]+))",
          with_record([](const ScanRecord& r, const httplib::Request&, httplib::Response& res) {
            json_reply(res, r.detail_json);
          }));
  svr.Get(R"(/api/scans/([^/]+)/points)",
          with_record([](const ScanRecord& r, const httplib::Request&, httplib::Response& res) {
            res.set_header("Cache-Control", "no-store");
            res.set_content(r.points, "application/octet-stream");
          }));
  svr.Get(R"(/scans/([^/]+)/files/(.*))",
          with_record([](const ScanRecord& r, const httplib::Request& req, httplib::Response& res) {
            if (r.dir.empty()) return error_reply(res, 404, "this scan has no output folder (use --out)");
            const auto p = resolve_under(r.dir, req.matches[2].str());
            if (!p) return error_reply(res, 404, "not found");
            send_file(res, *p);
          }));
  svr.Get(R"(/scans/([^/]+)/recording\.fscan)",
          with_record([](const ScanRecord& r, const httplib::Request&, httplib::Response& res) {
            if (r.recording.empty() || !stdfs::is_regular_file(r.recording))
              return error_reply(res, 404, "no recording");
            send_file(res, r.recording);
            res.set_header("Content-Disposition",
                           "attachment; filename=\"scan-" + std::to_string(r.id) + ".fscan\"");
          }));

  svr.Get("/api/events", [this](const httplib::Request&, httplib::Response& res) {
    auto sub = hub_.subscribe();
    if (!sub) {
      res.set_header("Retry-After", "5");
      return error_reply(res, 503, "too many event clients");
    }
    res.set_header("Cache-Control", "no-store");
    res.set_header("X-Accel-Buffering", "no");
    res.set_chunked_content_provider(
        "text/event-stream",
        [this, sub, first = true](std::size_t, httplib::DataSink& sink) mutable {
          std::string out;
          if (first) {
            out = "retry: 1000\n\n";
            first = false;
          }
          std::vector<Event> events;
          if (!hub_.next(*sub, events, std::chrono::milliseconds(1000))) {
            sink.done();
            return true;
          }
          for (const Event& e : events) out += "event: " + e.kind + "\ndata: " + *e.data + "\n\n";
          if (out.empty()) out = ": keep-alive\n\n";  // also finds a vanished client
          return sink.write(out.data(), out.size());
        },
        [this, sub](bool) { hub_.unsubscribe(sub); });
  });
}

}  // namespace fs::host::web
