// NatsConnection::end_subscription against a real nats-server (started here on a free port): Debian's nats.c
// 3.4.1 can use a subscription after the application freed it when a message for it is being read at that
// moment (nats.c#637). A subscriber that unsubscribes and destroys at once while messages pour in crashes
// within a few hundred rounds; end_subscription must not. Skipped when nats-server is missing (fails under
// CI=true, where toolchain/setup installs it).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>

#include "host/cli/child_process.hpp"
#include "host/fleet/nats_connection.hpp"

namespace {

namespace stdfs = std::filesystem;
using fs::host::cli::ChildProcess;
using fs::host::fleet::NatsConnection;
using fs::host::fleet::NatsOptions;

// A bare nats-server (no auth, no JetStream) on 127.0.0.1 and a free port, for one test.
class Server {
 public:
  explicit Server(const std::string& program) : port_(fs::host::cli::free_local_port()) {
    dir_ = stdfs::temp_directory_path() / ("fs-subscription-end-" + std::to_string(port_));
    stdfs::create_directories(dir_);
    proc_ = std::make_unique<ChildProcess>(
        std::vector<std::string>{program, "-a", "127.0.0.1", "-p", std::to_string(port_)},
        std::map<std::string, std::string>{}, dir_ / "nats-server.log");
    for (int i = 0; i < 500 && !fs::host::cli::local_port_open(port_); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ~Server() {
    proc_.reset();
    std::error_code ec;
    stdfs::remove_all(dir_, ec);
  }
  bool listening() const { return fs::host::cli::local_port_open(port_); }
  void kill() { proc_->stop(SIGKILL, 5000); }
  std::string url() const { return "nats://127.0.0.1:" + std::to_string(port_); }

 private:
  int port_;
  stdfs::path dir_;
  std::unique_ptr<ChildProcess> proc_;
};

std::string server_program() {
  const std::string p = fs::host::cli::find_program("nats-server").string();
  if (p.empty() && std::getenv("CI") != nullptr && std::string(std::getenv("CI")) == "true")
    ADD_FAILURE() << "nats-server missing under CI=true (toolchain/setup installs it)";
  return p;
}

// Publishes on `subject` from its own connection until stopped.
class Flood {
 public:
  Flood(const std::string& url, const std::string& subject) {
    NatsOptions o;
    o.url = url;
    o.name = "flood";
    connection_ = std::make_unique<NatsConnection>(o);
    thread_ = std::thread([this, subject] {
      const char payload[64] = "flood";
      while (!stop_.load()) {
        for (int i = 0; i < 100; ++i)
          natsConnection_Publish(connection_->get(), subject.c_str(), payload, sizeof payload);
        natsConnection_FlushTimeout(connection_->get(), 1000);
      }
    });
  }
  ~Flood() {
    stop_ = true;
    thread_.join();
  }

 private:
  std::unique_ptr<NatsConnection> connection_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

TEST(NatsSubscriptionEnd, ASubscriptionEndedWhileMessagesPourInIsNotUsedAfterItIsFreed) {
  const std::string program = server_program();
  if (program.empty()) GTEST_SKIP() << "nats-server not installed";
  Server server(program);
  ASSERT_TRUE(server.listening());
  Flood flood(server.url(), "flood");
  NatsOptions o;
  o.url = server.url();
  o.name = "subscriber";
  NatsConnection connection(o);
  int received = 0;
  for (int round = 0; round < 2000; ++round) {
    natsSubscription* sub = nullptr;
    ASSERT_EQ(natsConnection_SubscribeSync(&sub, connection.get(), "flood"), NATS_OK);
    natsMsg* m = nullptr;
    if (natsSubscription_NextMsg(&m, sub, 2000) == NATS_OK) {
      ++received;
      natsMsg_Destroy(m);
    }
    connection.end_subscription(sub);  // the read loop is delivering more to it right now
  }
  EXPECT_EQ(received, 2000);  // every round had messages in flight for its subscription
  EXPECT_EQ(connection.kept_subscriptions(), 0u);
}

TEST(NatsSubscriptionEnd, OneEndedWhileTheServerIsDownIsKeptUntilTheConnectionCloses) {
  const std::string program = server_program();
  if (program.empty()) GTEST_SKIP() << "nats-server not installed";
  Server server(program);
  ASSERT_TRUE(server.listening());
  NatsOptions o;
  o.url = server.url();
  o.name = "subscriber";
  auto connection = std::make_unique<NatsConnection>(o);
  natsSubscription* sub = nullptr;
  ASSERT_EQ(natsConnection_SubscribeSync(&sub, connection->get(), "anything"), NATS_OK);
  server.kill();
  for (int i = 0; i < 1000 && connection->connected(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_FALSE(connection->connected());
  connection->end_subscription(sub);
  EXPECT_EQ(connection->kept_subscriptions(), 1u);
  connection.reset();  // closes (joins the read loop), then destroys the kept subscription
}

}  // namespace
