#include "pipeline/imu_buffer.hpp"

#include <gtest/gtest.h>

#include <limits>

namespace kestrel::pipeline {
namespace {

ImuSample sample(Timestamp t, double v) {
  ImuSample s;
  s.t = t;
  s.gyro = Vec3(v, 2 * v, -v);
  s.acc = Vec3(0, 0, 9.81 + v);
  return s;
}

TEST(ImuBuffer, IntervalIsInterpolatedToFrameStamps) {
  ImuBuffer b;
  for (int i = 0; i <= 10; ++i) b.add(sample(i * 5'000'000, i));  // 200 Hz, value = index
  const auto s = b.between(12'500'000, 31'000'000);
  ASSERT_GE(s.size(), 2u);
  EXPECT_EQ(s.front().t, 12'500'000);
  EXPECT_DOUBLE_EQ(s.front().gyro.x(), 2.5);
  EXPECT_EQ(s.back().t, 31'000'000);
  EXPECT_NEAR(s.back().gyro.x(), 6.2, 1e-12);
  // interior samples are the raw ones at 15, 20, 25, 30 ms
  ASSERT_EQ(s.size(), 6u);
  EXPECT_EQ(s[1].t, 15'000'000);
  EXPECT_EQ(s[4].t, 30'000'000);
}

TEST(ImuBuffer, OutOfSpanAndBadSamples) {
  ImuBuffer b;
  b.add(sample(10, 0));
  b.add(sample(20, 1));
  b.add(sample(15, 2));  // out of order: rejected
  ImuSample nan = sample(30, 0);
  nan.acc.x() = std::numeric_limits<double>::quiet_NaN();
  b.add(nan);
  EXPECT_EQ(b.rejected(), 2u);
  EXPECT_TRUE(b.between(5, 20).empty());
  EXPECT_TRUE(b.between(10, 25).empty());
  EXPECT_EQ(b.between(10, 20).size(), 2u);
  b.drop_before(20);
  EXPECT_EQ(b.size(), 1u);
}

}  // namespace
}  // namespace kestrel::pipeline
