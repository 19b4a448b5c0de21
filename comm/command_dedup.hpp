#pragma once
// At-least-once delivery (outbox re-sends, station retries) plus this filter gives
// exactly-once execution: a command id seen before is acknowledged again but not executed.
// Remembers the last `capacity` ids (FIFO), enough to outlast any retry window.
#include <cstddef>
#include <deque>
#include <string>
#include <unordered_set>

namespace kestrel::comm {

class CommandDedup {
 public:
  explicit CommandDedup(std::size_t capacity = 4096) : capacity_(capacity) {}

  // True the first time an id is seen.
  bool first_time(const std::string& id) {
    if (seen_.count(id)) return false;
    seen_.insert(id);
    order_.push_back(id);
    if (order_.size() > capacity_) {
      seen_.erase(order_.front());
      order_.pop_front();
    }
    return true;
  }
  std::size_t size() const { return seen_.size(); }

 private:
  std::size_t capacity_;
  std::unordered_set<std::string> seen_;
  std::deque<std::string> order_;
};

}  // namespace kestrel::comm
