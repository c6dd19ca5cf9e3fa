#pragma once
// Server-Sent Events fan-out. publish() never waits for a client: it appends to each subscriber's bounded
// queue under one short lock (an event of a coalescing kind replaces the pending one of the same kind; a full
// queue drops its oldest event and counts it) and wakes the subscriber's HTTP thread, which does the sending.
// The number of subscribers is bounded (subscribe() returns null beyond it). A new subscriber first receives
// the latest event of every kind (the current status and the latest scan).
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace fs::host::web {

struct Event {
  std::string kind;                         // SSE "event:" name
  std::shared_ptr<const std::string> data;  // one line of JSON (shared by every subscriber)
};

class EventHub {
 public:
  struct Subscriber {
    std::deque<Event> queue;
    std::condition_variable cv;
    std::uint64_t dropped = 0;
  };

  EventHub(std::size_t max_subscribers, std::size_t queue_limit)
      : max_subscribers_(max_subscribers), queue_limit_(queue_limit == 0 ? 1 : queue_limit) {}

  std::shared_ptr<Subscriber> subscribe();  // null when max_subscribers are connected (or closed)
  void unsubscribe(const std::shared_ptr<Subscriber>& s);
  void publish(const std::string& kind, std::string data, bool coalesce);
  // Waits up to `timeout` for events and moves them into `out`; false once close() was called.
  bool next(Subscriber& s, std::vector<Event>& out, std::chrono::milliseconds timeout);
  void close();  // wakes every subscriber; next() returns false from now on

  std::size_t subscribers() const;
  std::uint64_t published() const;
  std::uint64_t dropped() const;  // over all subscribers, ever
  std::uint64_t rejected() const;

 private:
  std::size_t max_subscribers_, queue_limit_;
  mutable std::mutex mutex_;
  std::vector<std::shared_ptr<Subscriber>> subs_;
  std::map<std::string, Event> latest_;
  bool closed_ = false;
  std::uint64_t published_ = 0, dropped_ = 0, rejected_ = 0;
};

}  // namespace fs::host::web
