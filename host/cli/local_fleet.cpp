#include "host/cli/local_fleet.hpp"

#include <cctype>
#include <chrono>
#include <csignal>
#include <fstream>
#include <iterator>
#include <sstream>
#include <thread>

#include <fmt/format.h>

#include "common/error.hpp"

namespace fs::host::cli {
namespace {

namespace stdfs = std::filesystem;
using Clock = std::chrono::steady_clock;

stdfs::path find_dir(const char* built, const char* installed, const char* what) {
  for (const stdfs::path& p : {stdfs::path(built), stdfs::path(installed)})
    if (stdfs::is_directory(p)) return p;
  throw Error(fmt::format("cannot find {} (looked in {} and {})", what, built, installed));
}

std::string read_text(const stdfs::path& p) {
  std::ifstream f(p);
  if (!f) throw Error(p.string() + ": cannot read");
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

// The shipped one-node config with this fleet's ports, store and certificates: the same line replacements as
// the tests (tests/host/fleet), each setting line exactly once.
std::string fleet_config(const stdfs::path& deploy, const stdfs::path& dir, int port, int mqtt_port,
                         int http_port, bool tls) {
  const stdfs::path conf = deploy / "nats-server.conf";
  std::istringstream in(read_text(conf));
  const std::map<std::string, std::string> settings = {
      {"port: 4222", fmt::format("port: {}", port)},
      {"port: 1883", fmt::format("port: {}", mqtt_port)},
      {"http: \"127.0.0.1:8222\"", fmt::format("http: \"127.0.0.1:{}\"", http_port)},
      {"store_dir: \"/var/lib/facetscan/nats\"", fmt::format("store_dir: \"{}\"", (dir / "store").string())}};
  std::map<std::string, int> found;
  std::string out;
  bool in_client_tls = false;  // without tls: the top-level "tls {" block is left out (MQTT keeps its own)
  for (std::string line; std::getline(in, line);) {
    if (!tls && line.rfind("tls {", 0) == 0) in_client_tls = true;
    if (in_client_tls) {
      if (line == "}") in_client_tls = false;
      continue;
    }
    const auto first = line.find_first_not_of(' ');
    const std::string body = first == std::string::npos ? "" : line.substr(first);
    if (const auto it = settings.find(body); it != settings.end()) {
      line = line.substr(0, first) + it->second;
      ++found[it->first];
    }
    for (std::size_t at; (at = line.find("/etc/facetscan/nats/")) != std::string::npos;)
      line.replace(at, std::string("/etc/facetscan/nats/").size(), (dir / "certs").string() + "/");
    out += line + "\n";
  }
  for (const auto& [key, value] : settings)
    if (found[key] != 1) throw Error(fmt::format("{}: expected one line '{}'", conf.string(), key));
  return out;
}

std::map<std::string, std::string> read_env_file(const stdfs::path& p) {
  std::map<std::string, std::string> env;
  std::istringstream in(read_text(p));
  for (std::string line; std::getline(in, line);)
    if (const auto eq = line.find('='); eq != std::string::npos)
      env[line.substr(0, eq)] = line.substr(eq + 1);
  return env;
}

}  // namespace

void wait_for_port(ChildProcess& p, int port, const std::string& what) {
  const auto until = Clock::now() + std::chrono::seconds(30);
  while (!local_port_open(port)) {
    if (!p.running()) throw Error(fmt::format("{} exited before listening:\n{}", what, p.log_tail()));
    if (Clock::now() > until)
      throw Error(fmt::format("{} does not listen on port {}:\n{}", what, port, p.log_tail()));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

LocalFleet::LocalFleet(stdfs::path dir, stdfs::path bin, const fleet::FleetSettings& settings, bool tls)
    : dir_(stdfs::absolute(dir)), bin_(std::move(bin)), logs_(dir_ / "logs") {
  const stdfs::path deploy =
      find_dir(FACETSCAN_NATS_DEPLOY_DIR, "/usr/share/facetscan/nats", "the NATS configs");
  const stdfs::path nats_server = find_program("nats-server");
  if (nats_server.empty())
    throw Error("nats-server not found on PATH (Debian package nats-server; toolchain/setup installs it)");
  for (const char* fresh : {"store", "spool", "logs"}) stdfs::remove_all(dir_ / fresh);
  stdfs::create_directories(logs_);
  // Certificates and passwords (made once, kept for later runs): the shipped generator.
  if (!stdfs::exists(dir_ / "certs" / "ca.pem") || !stdfs::exists(dir_ / "certs" / "passwords.env")) {
    ChildProcess gen({"/bin/bash", (deploy / "gen-certs.sh").string(), (dir_ / "certs").string()}, {},
                     logs_ / "gen-certs.log");
    if (gen.wait(60000) != 0) throw Error("gen-certs.sh failed:\n" + gen.log_tail());
  }
  passwords_ = read_env_file(dir_ / "certs" / "passwords.env");
  if (tls) ca_ = (dir_ / "certs" / "ca.pem").string();
  const int port = free_local_port();
  std::ofstream(dir_ / "nats-server.conf")
      << fleet_config(deploy, dir_, port, free_local_port(), free_local_port(), tls);
  stdfs::copy_file(deploy / "accounts.conf", dir_ / "accounts.conf", stdfs::copy_options::overwrite_existing);
  url_ = fmt::format("{}://localhost:{}", tls ? "tls" : "nats", port);
  server_ = std::make_unique<ChildProcess>(
      std::vector<std::string>{nats_server.string(), "-c", (dir_ / "nats-server.conf").string()}, passwords_,
      logs_ / "nats-server.log");
  wait_for_port(*server_, port, "nats-server");
  fleet::NatsConnection admin(user("admin"));
  fleet::ensure_fleet(admin.js(), settings, true);
}

LocalFleet::~LocalFleet() { stop(); }

std::map<std::string, std::string> LocalFleet::user_env(const std::string& name) const {
  std::string upper;
  for (char c : name) upper += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  const auto it = passwords_.find("FACETSCAN_" + upper + "_PASSWORD");
  if (it == passwords_.end()) throw Error("no NATS user '" + name + "' in passwords.env");
  return {{"FACETSCAN_NATS_USER", name}, {"FACETSCAN_NATS_PASSWORD", it->second}};
}

fleet::NatsOptions LocalFleet::user(const std::string& name) const {
  fleet::NatsOptions o;
  o.url = url_;
  o.ca_file = ca_;
  o.user = name;
  o.password = user_env(name).at("FACETSCAN_NATS_PASSWORD");
  return o;
}

ChildProcess& LocalFleet::start_worker(const std::string& id, const std::vector<std::string>& library,
                                       const std::vector<std::string>& extra) {
  std::vector<std::string> args = {
      (bin_ / "facetscan").string(), "worker", "--nats", url_, "--worker-id", id};
  if (!ca_.empty()) args.insert(args.end(), {"--nats-ca", ca_});
  for (const auto& l : library) args.insert(args.end(), {"-l", l});
  args.insert(args.end(), extra.begin(), extra.end());
  workers_.push_back(std::make_unique<ChildProcess>(args, user_env("worker"), logs_ / (id + ".log")));
  return *workers_.back();
}

ChildProcess& LocalFleet::start_gateway(const std::string& scanner, int port) {
  std::vector<std::string> args = {(bin_ / "facetscan").string(),
                                   "serve",
                                   "--nats",
                                   url_,
                                   "--scanner",
                                   scanner,
                                   "--listen",
                                   fmt::format("127.0.0.1:{}", port),
                                   "--spool",
                                   (dir_ / "spool" / scanner).string(),
                                   "--stream"};
  if (!ca_.empty()) args.insert(args.end(), {"--nats-ca", ca_});
  gateways_.push_back(std::make_unique<ChildProcess>(args, user_env("gateway"),
                                                     logs_ / fmt::format("gateway-{}.log", scanner)));
  wait_for_port(*gateways_.back(), port, "the gateway of " + scanner);
  return *gateways_.back();
}

std::string LocalFleet::exited_process() {
  if (server_ && !server_->running())
    return fmt::format("nats-server exited ({}):\n{}", server_->log().string(), server_->log_tail());
  for (auto* group : {&workers_, &gateways_})
    for (auto& p : *group)
      if (!p->running())
        return fmt::format("{} exited ({}):\n{}", p->name(), p->log().string(), p->log_tail());
  return {};
}

void LocalFleet::stop() {
  for (auto& g : gateways_) g->stop(SIGTERM, 10000);
  for (auto& w : workers_) w->stop(SIGTERM, 30000);
  gateways_.clear();
  workers_.clear();
  if (server_) server_->stop(SIGTERM, 10000);
  server_.reset();
}

}  // namespace fs::host::cli
