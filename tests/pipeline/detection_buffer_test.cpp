#include "pipeline/detection_buffer.hpp"

#include <gtest/gtest.h>

#include <thread>

namespace kestrel::pipeline {
namespace {

detect::DetectionSet set_at(Timestamp t, int n) {
  detect::DetectionSet s;
  s.t = t;
  s.boxes.resize(n);
  return s;
}

TEST(DetectionBuffer, MatchesNearestWithin50ms) {
  DetectionBuffer b;
  b.put(set_at(1'000'000'000, 1));
  b.put(set_at(1'033'000'000, 2));
  auto m = b.match(1'030'000'000);
  ASSERT_TRUE(m);
  EXPECT_EQ(m->boxes.size(), 2u);
  EXPECT_FALSE(b.match(1'100'000'000));  // 67 ms from the nearest
  EXPECT_TRUE(b.match(1'083'000'000));   // exactly 50 ms
  EXPECT_EQ(b.matched(), 2u);
  EXPECT_EQ(b.missed(), 1u);
}

TEST(DetectionBuffer, LateSetsAreCounted) {
  DetectionBuffer b;
  b.tracked_up_to(2'000'000'000);
  b.put(set_at(1'000'000'000, 1));
  EXPECT_EQ(b.late(), 1u);
}

TEST(DetectionBuffer, LockStepWaitsForTheDetector) {
  DetectionBuffer b;
  std::thread producer([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    b.put(set_at(5, 3));
  });
  auto m = b.wait_and_match(5, std::chrono::milliseconds(2000));
  producer.join();
  ASSERT_TRUE(m);
  EXPECT_EQ(m->boxes.size(), 3u);
}

}  // namespace
}  // namespace kestrel::pipeline
