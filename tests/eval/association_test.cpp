#include "eval/association.hpp"

#include <gtest/gtest.h>

namespace kestrel::eval {
namespace {

using Idx = std::vector<std::size_t>;

TEST(Association, EvoTakesNearestStampAndMayReuseIt) {
  // Equal lengths: evo iterates the estimate and searches the reference.
  const Matches m = associate_evo({0.0, 1.0, 2.0}, {0.9, 1.05, 1.1}, 0.2);
  EXPECT_EQ(m.ref, (Idx{1, 1, 1}));
  EXPECT_EQ(m.est, (Idx{0, 1, 2}));
}

TEST(Association, TumUsesEachStampOnceSmallestDifferenceFirst) {
  const Matches m = associate_tum({0.0, 1.0, 2.0}, {0.9, 1.05, 1.1}, 0.2);
  EXPECT_EQ(m.ref, (Idx{1}));
  EXPECT_EQ(m.est, (Idx{1}));
}

TEST(Association, TumGreedyThenSortedByReference) {
  const Matches m = associate_tum({1.0, 2.0, 3.0}, {2.99, 1.01, 2.02}, 0.05);
  EXPECT_EQ(m.ref, (Idx{0, 1, 2}));
  EXPECT_EQ(m.est, (Idx{1, 2, 0}));
}

TEST(Association, EvoTieGoesToFirstIndexLikeArgmin) {
  // Reference longer: iterate the estimate, search the reference.
  const Matches m = associate_evo({0.0, 1.0}, {0.5}, 0.5);
  EXPECT_EQ(m.ref, (Idx{0}));
  EXPECT_EQ(m.est, (Idx{0}));
}

TEST(Association, EvoMaxDiffIsInclusiveTumExclusive) {
  EXPECT_EQ(associate_evo({0.0, 10.0}, {0.5}, 0.5).size(), 1u);
  EXPECT_EQ(associate_tum({0.0, 10.0}, {0.5}, 0.5).size(), 0u);
}

TEST(Association, OffsetIsAddedToTheEstimate) {
  // Estimate longer: iterate the reference, search estimate + offset.
  const Matches evo = associate_evo({10.0}, {0.0, 1.0, 2.0}, 0.01, 9.0);
  EXPECT_EQ(evo.est, (Idx{1}));
  // Reference longer: evo shifts the reference by -offset instead; same pairing.
  const Matches evo2 = associate_evo({8.0, 9.0, 10.0, 11.0}, {1.0, 2.0}, 0.01, 9.0);
  EXPECT_EQ(evo2.ref, (Idx{2, 3}));
  const Matches tum = associate_tum({10.0}, {0.0, 1.0, 2.0}, 0.01, 9.0);
  EXPECT_EQ(tum.est, (Idx{1}));
}

TEST(Association, EvoDropsStampsBeyondMaxDiff) {
  const Matches m = associate_evo({0.0, 1.0, 2.0, 3.0}, {0.001, 2.5, 3.002}, 0.01);
  EXPECT_EQ(m.ref, (Idx{0, 3}));
  EXPECT_EQ(m.est, (Idx{0, 2}));
}

TEST(Association, ByIndex) {
  const Matches m = associate_by_index(3);
  EXPECT_EQ(m.ref, (Idx{0, 1, 2}));
  EXPECT_EQ(m.est, (Idx{0, 1, 2}));
}

}  // namespace
}  // namespace kestrel::eval

namespace kestrel::eval {
namespace {

TEST(Association, RepeatedStampsFollowEachTool) {
  // associate.py keeps the last pose of a repeated stamp; evo keeps both and takes the first.
  const Matches tum = associate_tum({1.0, 2.0, 2.0, 3.0}, {2.001}, 0.02);
  EXPECT_EQ(tum.ref, (std::vector<std::size_t>{2}));
  const Matches evo = associate_evo({1.0, 2.0, 2.0, 3.0}, {2.001}, 0.02);
  EXPECT_EQ(evo.ref, (std::vector<std::size_t>{1}));
}

}  // namespace
}  // namespace kestrel::eval
