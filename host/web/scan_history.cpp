#include "host/web/scan_history.hpp"

#include <utility>

namespace fs::host::web {

std::size_t ScanHistory::add(std::shared_ptr<const ScanRecord> record) {
  std::shared_ptr<const ScanRecord> evicted;  // released outside the lock
  std::lock_guard lock(mutex_);
  for (auto& r : records_)
    if (r->id == record->id) {  // a newer version of a scan (its report was written meanwhile)
      evicted = std::exchange(r, std::move(record));
      return 0;
    }
  records_.push_back(std::move(record));
  std::size_t n = 0;
  while (records_.size() > capacity_) {
    evicted = std::move(records_.front());
    records_.pop_front();
    ++n;
  }
  return n;
}

std::shared_ptr<const ScanRecord> ScanHistory::find(std::uint64_t id) const {
  std::lock_guard lock(mutex_);
  for (const auto& r : records_)
    if (r->id == id) return r;
  return nullptr;
}

std::shared_ptr<const ScanRecord> ScanHistory::latest() const {
  std::lock_guard lock(mutex_);
  return records_.empty() ? nullptr : records_.back();
}

std::vector<std::shared_ptr<const ScanRecord>> ScanHistory::newest_first() const {
  std::lock_guard lock(mutex_);
  return {records_.rbegin(), records_.rend()};
}

std::size_t ScanHistory::size() const {
  std::lock_guard lock(mutex_);
  return records_.size();
}

std::size_t ScanHistory::bytes() const {
  std::lock_guard lock(mutex_);
  std::size_t n = 0;
  for (const auto& r : records_) n += r->bytes();
  return n;
}

}  // namespace fs::host::web
