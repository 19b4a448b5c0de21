#include "pipeline/stage_stats.hpp"

#include <chrono>
#include <thread>

#include <gtest/gtest.h>

namespace kestrel::pipeline {
namespace {

TEST(StageStats, PercentilesMatchNumpyLinear) {
  // numpy.percentile([1..10], [50, 90, 99]) = 5.5, 9.1, 9.91
  std::vector<double> v;
  for (int i = 10; i >= 1; --i) v.push_back(i);
  EXPECT_DOUBLE_EQ(percentile(v, 50), 5.5);
  EXPECT_NEAR(percentile(v, 90), 9.1, 1e-12);
  EXPECT_NEAR(percentile(v, 99), 9.91, 1e-12);
  const LatencySummary s = summarize(v);
  EXPECT_EQ(s.count, 10u);
  EXPECT_DOUBLE_EQ(s.mean_ms, 5.5);
  EXPECT_DOUBLE_EQ(s.max_ms, 10.0);
}

TEST(StageStats, LatencyWindowsFollowTheStream) {
  // 30 s of frames at 10 Hz, stamps from 100 s: 5 ms for 20 s, then 50 ms.
  std::vector<std::pair<double, double>> samples;
  for (int i = 0; i < 300; ++i) samples.emplace_back(100.0 + 0.1 * i, i < 200 ? 5.0 : 50.0);
  const std::vector<LatencyWindow> w = latency_windows(samples, 10.0);
  ASSERT_EQ(w.size(), 3u);
  EXPECT_DOUBLE_EQ(w[0].from_s, 0.0);
  EXPECT_DOUBLE_EQ(w[2].to_s, 30.0);
  EXPECT_EQ(w[0].latency.count + w[1].latency.count + w[2].latency.count, 300u);
  EXPECT_DOUBLE_EQ(w[1].latency.p99_ms, 5.0);
  EXPECT_DOUBLE_EQ(w[2].latency.p50_ms, 50.0);
  // A frame stamped at the end of the last window is in it, not in a window of its own.
  samples.emplace_back(130.0, 50.0);
  ASSERT_EQ(latency_windows(samples, 10.0).size(), 3u);
  EXPECT_EQ(latency_windows(samples, 10.0)[2].latency.count, 101u);
  // Stamps of a 30 Hz stream, whose last one rounds just past 30 s, make ten windows of 3 s.
  std::vector<std::pair<double, double>> stream;
  for (int i = 0; i <= 900; ++i) stream.emplace_back(i / 30.0 + 1e-9 * (i == 900), 1.0);
  EXPECT_EQ(latency_windows(stream, 3.0).size(), 10u);
  // A gap in the stream leaves its windows out; nothing to cut gives nothing.
  samples.emplace_back(200.0, 7.0);
  const std::vector<LatencyWindow> gap = latency_windows(samples, 10.0);
  ASSERT_EQ(gap.size(), 5u);  // the frame at 130 s now opens the window 30-40 s
  EXPECT_DOUBLE_EQ(gap[3].from_s, 30.0);
  EXPECT_DOUBLE_EQ(gap[4].from_s, 90.0);
  EXPECT_DOUBLE_EQ(gap[4].to_s, 100.0);
  EXPECT_EQ(gap[4].latency.count, 1u);
  EXPECT_TRUE(latency_windows({}, 10.0).empty());
  EXPECT_TRUE(latency_windows(samples, 0.0).empty());
}

// Each sample keeps when it was recorded, in order, so a long run's stage can be cut into
// windows along it; the values are the ones recorded.
TEST(StageStats, TimedSamplesKeepWhenEachWasRecorded) {
  StageStats stats;
  stats.record("a", 1.0);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  stats.record("b", 9.0);
  stats.record("a", 2.0);
  const auto a = stats.timed_samples("a");
  ASSERT_EQ(a.size(), 2u);
  EXPECT_EQ(a[0].second, 1.0);
  EXPECT_EQ(a[1].second, 2.0);
  EXPECT_GE(a[0].first, 0.0);
  EXPECT_GE(a[1].first - a[0].first, 0.019);  // a sleep lasts at least as long as asked
  const auto b = stats.timed_samples("b");
  ASSERT_EQ(b.size(), 1u);
  EXPECT_LE(b[0].first, a[1].first);
  EXPECT_TRUE(stats.timed_samples("none").empty());
  const auto windows = latency_windows(a, 0.01);
  ASSERT_GE(windows.size(), 2u);
  EXPECT_EQ(windows.front().latency.max_ms, 1.0);
  EXPECT_EQ(windows.back().latency.max_ms, 2.0);
}

TEST(StageStats, JsonHoldsStagesAndCounters) {
  StageStats st;
  st.record("tracking", 4.0);
  st.record("tracking", 6.0);
  st.count("detection.dropped", 3);
  const std::string j = st.to_json();
  EXPECT_NE(j.find("\"tracking\""), std::string::npos);
  EXPECT_NE(j.find("\"p50_ms\": 5.0"), std::string::npos);
  EXPECT_NE(j.find("\"detection.dropped\": 3"), std::string::npos);
}

}  // namespace
}  // namespace kestrel::pipeline
