#include "pipeline/stage_stats.hpp"

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
