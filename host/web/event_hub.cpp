#include "host/web/event_hub.hpp"

#include <algorithm>

namespace fs::host::web {

std::shared_ptr<EventHub::Subscriber> EventHub::subscribe() {
  auto s = std::make_shared<Subscriber>();
  std::lock_guard lock(mutex_);
  if (closed_ || subs_.size() >= max_subscribers_) {
    ++rejected_;
    return nullptr;
  }
  for (const auto& [kind, e] : latest_) s->queue.push_back(e);
  subs_.push_back(s);
  return s;
}

void EventHub::unsubscribe(const std::shared_ptr<Subscriber>& s) {
  std::lock_guard lock(mutex_);
  subs_.erase(std::remove(subs_.begin(), subs_.end(), s), subs_.end());
}

void EventHub::publish(const std::string& kind, std::string data, bool coalesce) {
  Event e{kind, std::make_shared<const std::string>(std::move(data))};  // allocated outside the lock
  std::lock_guard lock(mutex_);
  ++published_;
  latest_[kind] = e;
  for (const auto& s : subs_) {
    bool replaced = false;
    if (coalesce)
      for (Event& q : s->queue)
        if (q.kind == kind) {
          q.data = e.data;
          replaced = true;
          break;
        }
    if (!replaced) {
      if (s->queue.size() >= queue_limit_) {
        s->queue.pop_front();
        ++s->dropped;
        ++dropped_;
      }
      s->queue.push_back(e);
    }
    s->cv.notify_one();
  }
}

bool EventHub::next(Subscriber& s, std::vector<Event>& out, std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  s.cv.wait_for(lock, timeout, [&] { return closed_ || !s.queue.empty(); });
  if (closed_) return false;
  while (!s.queue.empty()) {
    out.push_back(std::move(s.queue.front()));
    s.queue.pop_front();
  }
  return true;
}

void EventHub::close() {
  std::lock_guard lock(mutex_);
  closed_ = true;
  for (const auto& s : subs_) s->cv.notify_all();
}

std::size_t EventHub::subscribers() const {
  std::lock_guard lock(mutex_);
  return subs_.size();
}
std::uint64_t EventHub::published() const {
  std::lock_guard lock(mutex_);
  return published_;
}
std::uint64_t EventHub::dropped() const {
  std::lock_guard lock(mutex_);
  return dropped_;
}
std::uint64_t EventHub::rejected() const {
  std::lock_guard lock(mutex_);
  return rejected_;
}

}  // namespace fs::host::web
