#include "firmware/stream/queued_publisher.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>

namespace fs::fw {

QueuedPublisher::QueuedPublisher(wire::FrameSink& sink, QueuedPublisherConfig cfg, const LinkState* link)
    : sink_(sink), cfg_(cfg), link_(link), writer_(sink) {
  if (cfg_.slots < 2) cfg_.slots = 2;
  cfg_.max_points = std::min(cfg_.max_points, msg::kMaxStripePoints);
  ring_.resize(cfg_.slots);
  for (auto& s : ring_) s.points.resize(cfg_.max_points);
  fault_msg_.text.reserve(msg::kMaxFaultText);
  thread_ = std::thread([this] { run(); });
}

QueuedPublisher::~QueuedPublisher() {
  stop_ = true;
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

std::uint32_t QueuedPublisher::stripes_dropped() const {
  return dropped_.load() + (link_ ? link_->frames_dropped() : 0);
}

QueuedPublisher::Slot* QueuedPublisher::acquire(bool may_drop) {
  for (;;) {
    const std::uint64_t h = head_.load(std::memory_order_relaxed);
    if (h - tail_.load(std::memory_order_acquire) < ring_.size()) return &ring_[h % ring_.size()];
    if (failed_.load()) return nullptr;
    if (may_drop && !cfg_.block_when_full) return nullptr;
    cv_.notify_one();
    std::this_thread::yield();
  }
}

void QueuedPublisher::commit() {
  head_.store(head_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
  cv_.notify_one();
}

void QueuedPublisher::begin(const msg::ScanBegin& m) {
  flush();
  std::lock_guard<std::mutex> lock(mu_);
  writer_.send(m);
  written_.fetch_add(1);
}

bool QueuedPublisher::stripe(const msg::Stripe& m) {
  Slot* s = acquire(true);
  if (!s) {
    dropped_.fetch_add(1);
    return false;
  }
  s->type = msg::Type::Stripe;
  s->header = m.header;
  s->npoints = static_cast<std::uint32_t>(std::min<std::size_t>(m.points.size(), s->points.size()));
  std::copy_n(m.points.data(), s->npoints, s->points.data());
  commit();
  return true;
}

void QueuedPublisher::heartbeat(const msg::Heartbeat& m) {
  Slot* s = acquire(false);
  if (!s) return;
  s->type = msg::Type::Heartbeat;
  s->heartbeat = m;
  commit();
}

void QueuedPublisher::fault(std::uint32_t code, const char* text) {
  Slot* s = acquire(false);
  if (!s) return;
  s->type = msg::Type::Fault;
  s->fault_code = code;
  const std::size_t n = text ? strnlen(text, msg::kMaxFaultText) : 0;
  std::memcpy(s->fault_text, text ? text : "", n);
  s->fault_len = static_cast<std::uint32_t>(n);
  commit();
}

void QueuedPublisher::end(const msg::ScanEnd& m) {
  Slot* s = acquire(false);
  if (!s) return;
  s->type = msg::Type::ScanEnd;
  s->end = m;
  commit();
}

void QueuedPublisher::flush() {
  while (tail_.load() != head_.load() && !failed_.load()) {
    cv_.notify_one();
    std::this_thread::sleep_for(std::chrono::microseconds(100));
  }
  std::lock_guard<std::mutex> lock(mu_);
  if (error_) std::rethrow_exception(error_);
}

void QueuedPublisher::run() {
  for (;;) {
    const std::uint64_t t = tail_.load(std::memory_order_relaxed);
    if (t == head_.load(std::memory_order_acquire)) {
      if (stop_.load()) return;
      std::unique_lock<std::mutex> lock(mu_);
      cv_.wait_for(lock, std::chrono::milliseconds(1));
      continue;
    }
    Slot& s = ring_[t % ring_.size()];
    if (!failed_.load()) {
      std::lock_guard<std::mutex> lock(mu_);
      try {
        switch (s.type) {
          case msg::Type::Stripe:
            stripe_msg_.header = s.header;
            stripe_msg_.points = std::span<msg::StripePoint>(s.points.data(), s.npoints);
            writer_.send(stripe_msg_);
            break;
          case msg::Type::Heartbeat:
            writer_.send(s.heartbeat);
            break;
          case msg::Type::ScanEnd:
            writer_.send(s.end);
            break;
          case msg::Type::Fault:
            fault_msg_.code = s.fault_code;
            fault_msg_.text.assign(s.fault_text, s.fault_len);
            writer_.send(fault_msg_);
            break;
          case msg::Type::ScanBegin:
            break;
        }
        written_.fetch_add(1);
      } catch (...) {
        error_ = std::current_exception();
        failed_ = true;
      }
    }
    tail_.store(t + 1, std::memory_order_release);
  }
}

}  // namespace fs::fw
