#pragma once
// Detections meet frames here (DESIGN.md: DetectionBuffer, match by stamp within 50 ms). The
// detection thread puts result sets in; the tracking thread asks for the set nearest to its
// frame's stamp. Sets too far away in time count as misses; sets that arrive after their frame
// was tracked count as late.
#include <chrono>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>

#include "detect/detection.hpp"

namespace kestrel::pipeline {

class DetectionBuffer {
 public:
  explicit DetectionBuffer(Timestamp tolerance_ns = 50'000'000) : tolerance_(tolerance_ns) {}

  void put(detect::DetectionSet set);
  // Nearest set within the tolerance; nullopt (a miss) otherwise.
  std::optional<detect::DetectionSet> match(Timestamp t);
  // As match(), but first waits up to `timeout` for a set at exactly t (lock-step mode).
  std::optional<detect::DetectionSet> wait_and_match(Timestamp t,
                                                     std::chrono::milliseconds timeout);
  // Marks frames up to t as tracked: later sets for them are late, older sets are dropped.
  void tracked_up_to(Timestamp t);

  std::size_t matched() const;
  std::size_t missed() const;
  std::size_t late() const;

 private:
  std::optional<detect::DetectionSet> match_locked(Timestamp t);

  const Timestamp tolerance_;
  mutable std::mutex mutex_;
  std::condition_variable arrived_;
  std::deque<detect::DetectionSet> sets_;
  Timestamp tracked_until_ = -1;
  std::size_t matched_ = 0, missed_ = 0, late_ = 0;
};

}  // namespace kestrel::pipeline
