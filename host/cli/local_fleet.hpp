#pragma once
// A fleet on this machine (`facetscan demo --fleet`, bench_fleet): a nats-server from the shipped one-node
// config (toolchain/deploy/nats: TLS with certificates from gen-certs.sh, JetStream on file storage, the
// least-privilege users) on free ports with a fresh store, the streams set up, and the fleet's processes
// (`facetscan worker`, `facetscan serve --nats`) started as the right users. Everything lives in one folder:
// DIR/nats-server.conf, DIR/store/, DIR/certs/ (kept across runs), DIR/spool/, DIR/logs/<process>.log.
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "host/cli/child_process.hpp"
#include "host/fleet/nats_connection.hpp"
#include "host/fleet/streams.hpp"

namespace fs::host::cli {

class LocalFleet {
 public:
  // Starts the server and creates the streams. `bin` holds facetscan and facetscan-fw-hil. Throws fs::Error
  // naming what is missing (nats-server, the configs) or what failed, with its log's tail. tls = false leaves
  // the client TLS block out (plain nats:// on loopback: bench_fleet measures what TLS costs).
  LocalFleet(std::filesystem::path dir, std::filesystem::path bin, const fleet::FleetSettings& settings = {},
             bool tls = true);
  ~LocalFleet();  // stops every process (workers last but one, the server last)
  LocalFleet(const LocalFleet&) = delete;
  LocalFleet& operator=(const LocalFleet&) = delete;

  const std::string& url() const { return url_; }
  const std::string& ca() const { return ca_; }
  const std::filesystem::path& logs() const { return logs_; }
  const std::filesystem::path& bin() const { return bin_; }
  // Connection options of a user of accounts.conf (admin, gateway, worker, shopfloor, client).
  fleet::NatsOptions user(const std::string& name) const;
  std::map<std::string, std::string> user_env(const std::string& name) const;

  ChildProcess& start_worker(const std::string& id, const std::vector<std::string>& library,
                             const std::vector<std::string>& extra = {});
  // A streaming gateway (serve --nats --stream) for one scanner id, listening on 127.0.0.1:port (waits until
  // it listens).
  ChildProcess& start_gateway(const std::string& scanner, int port);
  // "" while every started process runs, else which one exited, with its log's tail.
  std::string exited_process();
  // SIGTERM to every process (gateways, then workers: they finish their scan), then the server.
  void stop();

 private:
  std::filesystem::path dir_, bin_, logs_;
  std::string url_, ca_;
  std::map<std::string, std::string> passwords_;
  std::unique_ptr<ChildProcess> server_;
  std::vector<std::unique_ptr<ChildProcess>> workers_, gateways_;
};

// Waits until 127.0.0.1:port accepts connections; throws naming `what` (with its log) when the process exits
// first or after 30 s.
void wait_for_port(ChildProcess& process, int port, const std::string& what);

}  // namespace fs::host::cli
