#pragma once
// Publisher that copies each message into a preallocated single-producer/single-consumer ring; an output
// thread encodes the messages as wire frames (common/wire.hpp) and writes them to a FrameSink (TCP stream,
// .fscan file, both, a buffer). The producer never blocks unless `block_when_full` is set (virtual-time runs,
// where blocking costs nothing and the run must stay lossless); otherwise a full ring drops the stripe and
// counts it. Heartbeats, faults and ScanEnd are never dropped silently: when the ring is full they wait.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

#include "common/wire.hpp"
#include "firmware/stream/publisher.hpp"

namespace fs::fw {

struct QueuedPublisherConfig {
  std::uint32_t slots = 64;         // ring capacity (messages)
  std::uint32_t max_points = 4096;  // stripe points per message (>= image height)
  bool block_when_full = false;
};

// Optional link state for streaming sinks (TcpSink); the publisher reports it through host_connected().
class LinkState {
 public:
  virtual ~LinkState() = default;
  virtual bool connected() const = 0;
  virtual std::uint32_t frames_dropped() const = 0;  // stripes lost in the link's own buffer
};

class QueuedPublisher final : public Publisher {
 public:
  QueuedPublisher(wire::FrameSink& sink, QueuedPublisherConfig cfg = {}, const LinkState* link = nullptr);
  ~QueuedPublisher() override;
  QueuedPublisher(const QueuedPublisher&) = delete;
  QueuedPublisher& operator=(const QueuedPublisher&) = delete;

  void begin(const msg::ScanBegin& m) override;
  bool stripe(const msg::Stripe& m) override;
  void heartbeat(const msg::Heartbeat& m) override;
  void fault(std::uint32_t code, const char* text) override;
  void end(const msg::ScanEnd& m) override;
  bool host_connected() const override { return link_ == nullptr || link_->connected(); }
  std::uint32_t stripes_dropped() const override;

  // Waits until everything queued has been written (or the sink failed). Rethrows a sink error.
  void flush();
  std::uint64_t frames_written() const { return written_.load(); }
  // Stripes dropped because the ring was full (never handed to the sink).
  std::uint32_t ring_dropped() const { return dropped_.load(); }

 private:
  struct Slot {
    msg::Type type = msg::Type::Heartbeat;
    msg::StripeHeader header;
    std::uint32_t npoints = 0;
    std::vector<msg::StripePoint> points;
    msg::Heartbeat heartbeat;
    msg::ScanEnd end;
    std::uint32_t fault_code = 0;
    std::uint32_t fault_len = 0;
    char fault_text[msg::kMaxFaultText] = {};
  };
  Slot* acquire(bool may_drop);
  void commit();
  void run();

  wire::FrameSink& sink_;
  QueuedPublisherConfig cfg_;
  const LinkState* link_;
  wire::FrameWriter writer_;
  std::vector<Slot> ring_;
  std::atomic<std::uint64_t> head_{0}, tail_{0};
  std::atomic<bool> stop_{false}, failed_{false};
  std::atomic<std::uint32_t> dropped_{0};
  std::atomic<std::uint64_t> written_{0};
  std::mutex mu_;
  std::condition_variable cv_;
  std::exception_ptr error_;
  msg::Fault fault_msg_;  // reused by the output thread (text capacity reserved)
  msg::Stripe stripe_msg_;
  std::thread thread_;
};

}  // namespace fs::fw
