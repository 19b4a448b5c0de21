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

}  // namespace
}  // namespace kestrel::pipeline
