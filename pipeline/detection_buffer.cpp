#include "pipeline/detection_buffer.hpp"

#include <algorithm>
#include <cstdlib>

namespace kestrel::pipeline {

void DetectionBuffer::put(detect::DetectionSet set) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (set.t < tracked_until_ - tolerance_) {
    ++late_;
    return;
  }
  const auto pos = std::upper_bound(sets_.begin(), sets_.end(), set.t,
                                    [](Timestamp t, const auto& s) { return t < s.t; });
  sets_.insert(pos, std::move(set));
  arrived_.notify_all();
}

std::optional<detect::DetectionSet> DetectionBuffer::match_locked(Timestamp t) {
  const detect::DetectionSet* best = nullptr;
  for (const auto& s : sets_) {
    if (std::llabs(s.t - t) <= tolerance_ &&
        (!best || std::llabs(s.t - t) < std::llabs(best->t - t))) {
      best = &s;
    }
  }
  if (!best) {
    ++missed_;
    return std::nullopt;
  }
  ++matched_;
  return *best;
}

std::optional<detect::DetectionSet> DetectionBuffer::match(Timestamp t) {
  std::lock_guard<std::mutex> lock(mutex_);
  return match_locked(t);
}

std::optional<detect::DetectionSet> DetectionBuffer::wait_and_match(
    Timestamp t, std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mutex_);
  arrived_.wait_for(lock, timeout, [&] {
    return std::any_of(sets_.begin(), sets_.end(), [&](const auto& s) { return s.t >= t; });
  });
  return match_locked(t);
}

void DetectionBuffer::tracked_up_to(Timestamp t) {
  std::lock_guard<std::mutex> lock(mutex_);
  tracked_until_ = std::max(tracked_until_, t);
  while (!sets_.empty() && sets_.front().t < t - 2 * tolerance_) sets_.pop_front();
}

std::size_t DetectionBuffer::matched() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return matched_;
}
std::size_t DetectionBuffer::missed() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return missed_;
}
std::size_t DetectionBuffer::late() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return late_;
}

}  // namespace kestrel::pipeline
