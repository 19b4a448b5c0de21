#pragma once
// The only way pipeline threads hand work to each other (DESIGN.md). Bounded, with an explicit
// policy for a full queue, and it counts what it dropped so `timing.json` can report it.
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <optional>

namespace kestrel::pipeline {

enum class FullPolicy {
  kBlock,       // producer waits: back-pressure (mapping never drops keyframes)
  kDropOldest,  // newest wins (detection, video): the oldest queued item is discarded
};

template <typename T>
class BoundedQueue {
 public:
  BoundedQueue(std::size_t capacity, FullPolicy policy)
      : capacity_(capacity == 0 ? 1 : capacity), policy_(policy) {}

  // Returns false when the queue is closed (the item is not queued).
  bool push(T item) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (policy_ == FullPolicy::kBlock) {
      not_full_.wait(lock, [&] { return closed_ || items_.size() < capacity_; });
    }
    if (closed_) return false;
    if (items_.size() >= capacity_) {
      items_.pop_front();
      ++dropped_;
    }
    items_.push_back(std::move(item));
    ++pushed_;
    not_empty_.notify_one();
    return true;
  }

  // Blocks until an item arrives; nullopt once the queue is closed and drained.
  std::optional<T> pop() {
    std::unique_lock<std::mutex> lock(mutex_);
    not_empty_.wait(lock, [&] { return closed_ || !items_.empty(); });
    return take_front();
  }

  // As pop(), but wake() also ends the wait: nullopt then, and after close() once drained
  // (closed() tells the two apart). A consumer with other work that arrives by another way (the
  // tracking thread's mapping results) does it while no item waits, not when the next one comes.
  std::optional<T> pop_or_wake() {
    std::unique_lock<std::mutex> lock(mutex_);
    not_empty_.wait(lock, [&] { return closed_ || woken_ || !items_.empty(); });
    woken_ = false;
    return take_front();
  }

  // Ends one pop_or_wake() wait, the current one or, if none waits, the next.
  void wake() {
    std::lock_guard<std::mutex> lock(mutex_);
    woken_ = true;
    not_empty_.notify_all();
  }

  std::optional<T> try_pop() {
    std::lock_guard<std::mutex> lock(mutex_);
    return take_front();
  }

  // No more pushes; consumers drain what is left, then pop() returns nullopt.
  void close() {
    std::lock_guard<std::mutex> lock(mutex_);
    closed_ = true;
    not_empty_.notify_all();
    not_full_.notify_all();
  }

  bool closed() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return closed_;
  }

  std::size_t size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return items_.size();
  }
  std::size_t dropped() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return dropped_;
  }
  std::size_t pushed() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return pushed_;
  }
  std::size_t capacity() const { return capacity_; }

 private:
  // The front item, if any; mutex_ held.
  std::optional<T> take_front() {
    if (items_.empty()) return std::nullopt;
    T item = std::move(items_.front());
    items_.pop_front();
    not_full_.notify_one();
    return item;
  }

  const std::size_t capacity_;
  const FullPolicy policy_;
  mutable std::mutex mutex_;
  std::condition_variable not_empty_;
  std::condition_variable not_full_;
  std::deque<T> items_;
  bool closed_ = false;
  bool woken_ = false;
  std::size_t dropped_ = 0;
  std::size_t pushed_ = 0;
};

}  // namespace kestrel::pipeline
