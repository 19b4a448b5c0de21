#include "pipeline/bounded_queue.hpp"

#include <gtest/gtest.h>

#include <thread>
#include <vector>

namespace kestrel::pipeline {
namespace {

TEST(BoundedQueue, DropOldestKeepsNewestAndCounts) {
  BoundedQueue<int> q(3, FullPolicy::kDropOldest);
  for (int i = 0; i < 10; ++i) EXPECT_TRUE(q.push(i));
  EXPECT_EQ(q.dropped(), 7u);
  EXPECT_EQ(q.size(), 3u);
  EXPECT_EQ(*q.pop(), 7);
  EXPECT_EQ(*q.pop(), 8);
  EXPECT_EQ(*q.pop(), 9);
  EXPECT_FALSE(q.try_pop());
}

TEST(BoundedQueue, BlockingQueueLosesNothingAcrossThreads) {
  BoundedQueue<int> q(2, FullPolicy::kBlock);
  constexpr int kItems = 5000;
  std::thread producer([&] {
    for (int i = 0; i < kItems; ++i) ASSERT_TRUE(q.push(i));
    q.close();
  });
  std::vector<int> got;
  while (auto v = q.pop()) got.push_back(*v);
  producer.join();
  ASSERT_EQ(got.size(), static_cast<std::size_t>(kItems));
  for (int i = 0; i < kItems; ++i) ASSERT_EQ(got[i], i);
  EXPECT_EQ(q.dropped(), 0u);
}

TEST(BoundedQueue, CloseWakesConsumersAndRejectsPushes) {
  BoundedQueue<int> q(1, FullPolicy::kBlock);
  std::thread consumer([&] { EXPECT_FALSE(q.pop().has_value()); });
  q.close();
  consumer.join();
  EXPECT_FALSE(q.push(1));
}

TEST(BoundedQueue, WakeEndsOneWaitWithoutLosingItems) {
  BoundedQueue<int> q(4, FullPolicy::kBlock);
  // A wake with nobody waiting ends the next wait, once.
  q.wake();
  EXPECT_FALSE(q.pop_or_wake().has_value());
  EXPECT_FALSE(q.closed());
  ASSERT_TRUE(q.push(1));
  EXPECT_EQ(*q.pop_or_wake(), 1);

  // A waiting consumer is woken from another thread; items pushed later still come, in order.
  std::vector<int> got;
  int wakes = 0;
  std::thread consumer([&] {
    for (;;) {
      if (auto v = q.pop_or_wake()) {
        got.push_back(*v);
      } else if (q.closed()) {
        return;
      } else {
        ++wakes;
      }
    }
  });
  q.wake();
  for (int i = 0; i < 100; ++i) ASSERT_TRUE(q.push(i));
  q.close();
  consumer.join();
  ASSERT_EQ(got.size(), 100u);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(got[i], i);
  EXPECT_LE(wakes, 1);
}

}  // namespace
}  // namespace kestrel::pipeline
