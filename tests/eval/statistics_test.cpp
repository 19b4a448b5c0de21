#include "eval/error_statistics.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "eval/pair_filter.hpp"

namespace kestrel::eval {
namespace {

TEST(Statistics, MatchesNumpyOnSmallVector) {
  // numpy: rmse sqrt(mean(e^2)), std population, median of even length = mean of middle two.
  const ErrorStatistics s = compute_statistics({4.0, 1.0, 3.0, 2.0});
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_DOUBLE_EQ(s.std, std::sqrt(1.25));
  EXPECT_DOUBLE_EQ(s.sse, 30.0);
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(7.5));
  EXPECT_DOUBLE_EQ(s.min, 1.0);
  EXPECT_DOUBLE_EQ(s.max, 4.0);
  EXPECT_EQ(s.count, 4u);
  EXPECT_DOUBLE_EQ(compute_statistics({3.0, 1.0, 2.0}).median, 2.0);
  EXPECT_EQ(compute_statistics({}).count, 0u);
}

TEST(Statistics, PairwiseSumIsAccurate) {
  // 0.1 added 10^6 times: naive summation drifts by ~1e-6, pairwise stays within ~1e-10.
  const std::vector<double> v(1000000, 0.1);
  EXPECT_NEAR(numpy_sum(v.data(), v.size()), 100000.0, 1e-8);
  const std::vector<double> small = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11};
  EXPECT_DOUBLE_EQ(numpy_sum(small.data(), small.size()), 66.0);
}

TEST(PairFilter, ByIndexConsecutiveAndAll) {
  EXPECT_EQ(filter_pairs_by_index(7, 3, false), (IdPairs{{0, 3}, {3, 6}}));
  EXPECT_EQ(filter_pairs_by_index(5, 3, true), (IdPairs{{0, 3}, {1, 4}}));
}

TEST(PairFilter, ByPathFollowsEvo) {
  // Poses 1 m apart on a line: the path reaches 2 m at index 2, then 2 m more at 4, 6.
  std::vector<Mat4> poses(8, Mat4::Identity());
  for (int k = 0; k < 8; ++k) poses[static_cast<std::size_t>(k)](0, 3) = k;
  EXPECT_EQ(filter_pairs_by_path(poses, 2.0, 0.0, false), (IdPairs{{2, 4}, {4, 6}}));
  const IdPairs all = filter_pairs_by_path(poses, 3.0, 0.3, true);
  ASSERT_EQ(all.size(), 5u);
  EXPECT_EQ(all.front(), (std::pair<std::size_t, std::size_t>{0, 3}));
  EXPECT_EQ(all.back(), (std::pair<std::size_t, std::size_t>{4, 7}));
}

}  // namespace
}  // namespace kestrel::eval
