#include "loop/keyframe_database.hpp"

#include <gtest/gtest.h>

#include <set>

namespace kestrel::loop {
namespace {

BowVector make_bow(std::vector<std::pair<WordId, double>> entries) {
  double total = 0.0;
  for (const auto& e : entries) total += e.second;
  for (auto& e : entries) e.second /= total;
  return BowVector{std::move(entries)};
}

TEST(KeyframeDatabase, L1ScoreMatchesDbow2Definition) {
  const BowVector a = make_bow({{1, 1.0}, {2, 1.0}, {5, 2.0}});
  const BowVector b = make_bow({{2, 1.0}, {5, 1.0}, {9, 2.0}});
  double l1 = 0.0;  // |a - b|_1 by hand: words 1, 2, 5, 9
  l1 += 0.25 + std::abs(0.25 - 0.25) + std::abs(0.5 - 0.25) + 0.5;
  EXPECT_NEAR(l1_score(a, b), 1.0 - 0.5 * l1, 1e-12);
  EXPECT_NEAR(l1_score(a, a), 1.0, 1e-12);
  EXPECT_NEAR(l1_score(a, make_bow({{7, 1.0}})), 0.0, 1e-12);
}

TEST(KeyframeDatabase, QueryRanksExcludesAndNormalises) {
  KeyframeDatabase db(
      {.min_score = 0.01, .min_normalized = 0.5, .min_ratio_to_best = 0.0, .max_candidates = 10});
  db.add(0, make_bow({{1, 1.0}, {2, 1.0}, {3, 1.0}, {4, 1.0}}));  // the same place as the query
  db.add(1, make_bow({{1, 1.0}, {2, 1.0}, {8, 2.0}}));            // half of it
  db.add(2, make_bow({{9, 1.0}}));                                // elsewhere
  db.add(3, make_bow({{1, 1.0}, {2, 1.0}, {3, 1.0}, {7, 1.0}}));  // the query's neighbour
  const BowVector q = make_bow({{1, 1.0}, {2, 1.0}, {3, 1.0}, {4, 1.0}});

  auto c = db.query(q, {}, {3});
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[0].id, 0);
  EXPECT_NEAR(c[0].score, 1.0, 1e-12);
  EXPECT_EQ(c[1].id, 1);
  EXPECT_NEAR(c[1].score, 0.5, 1e-12);

  // Normalised by the neighbour's 0.75: keyframe 1 (0.5 / 0.75) passes 0.5, not 0.7.
  c = db.query(q, {3}, {3});
  ASSERT_EQ(c.size(), 2u);
  EXPECT_NEAR(c[1].normalized, 0.5 / 0.75, 1e-12);
  KeyframeDatabase strict(
      {.min_score = 0.01, .min_normalized = 0.7, .min_ratio_to_best = 0.0, .max_candidates = 10});
  for (KeyframeId id = 0; id < 4; ++id) strict.add(id, *db.bow(id));
  c = strict.query(q, {3}, {3});
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].id, 0);

  // Keyframe 1 scores 0.5 of the best (1.0): dropped by a 0.75 ratio to the best.
  KeyframeDatabase ratio({.min_score = 0.01, .min_normalized = 0.0, .min_ratio_to_best = 0.75});
  for (KeyframeId id = 0; id < 4; ++id) ratio.add(id, *db.bow(id));
  c = ratio.query(q, {3}, {3});
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].id, 0);

  db.erase(0);
  c = db.query(q, {}, {3});
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].id, 1);
  EXPECT_EQ(db.size(), 3u);
}

// ORB-SLAM's rule: a candidate must look as much like the query as the query's least similar
// neighbour does. Asked to beat the most similar one instead, a revisit rarely could while a
// crowd crossed the view (market: 5-7 loops against its still twin's 20-26).
TEST(KeyframeDatabase, NormalisesByTheLeastSimilarNeighbourUnlessAskedForTheMost) {
  KeyframeDatabaseOptions least{
      .min_score = 0.01, .min_normalized = 1.0, .min_ratio_to_best = 0.0, .max_candidates = 10};
  KeyframeDatabaseOptions most = least;
  most.least_similar_neighbour = false;
  EXPECT_TRUE(KeyframeDatabaseOptions{}.least_similar_neighbour);
  KeyframeDatabase db(least);
  db.add(0, make_bow({{1, 1.0}, {2, 1.0}, {3, 1.0}, {4, 1.0}}));  // the same place as the query
  db.add(1, make_bow({{1, 1.0}, {2, 1.0}, {8, 2.0}}));            // half of it: 0.5
  db.add(3, make_bow({{1, 1.0}, {2, 1.0}, {3, 1.0}, {7, 1.0}}));  // a neighbour at 0.75
  db.add(4, make_bow({{1, 1.0}, {5, 1.0}, {6, 1.0}, {7, 1.0}}));  // a neighbour at 0.25
  const BowVector q = make_bow({{1, 1.0}, {2, 1.0}, {3, 1.0}, {4, 1.0}});
  const std::set<KeyframeId> exclude{3, 4};

  auto c = db.query(q, {3, 4}, exclude);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[1].id, 1);
  EXPECT_NEAR(c[1].normalized, 0.5 / 0.25, 1e-12);

  c = db.query(q, {3, 4}, exclude, most);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].id, 0);
  EXPECT_NEAR(c[0].normalized, 1.0 / 0.75, 1e-12);

  // Neighbours not in the database are skipped, not read as a score of 0.
  c = db.query(q, {4, 99}, exclude);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_NEAR(c[1].normalized, 0.5 / 0.25, 1e-12);
}

TEST(ConsistencyChecker, AcceptsAfterThreeConsecutiveOverlappingQueries) {
  ConsistencyChecker checker(3);
  EXPECT_TRUE(checker.update({{10, 11}}).empty());
  EXPECT_TRUE(checker.update({{11, 12}, {50}}).empty());
  const auto accepted = checker.update({{40}, {12, 13}});
  ASSERT_EQ(accepted.size(), 1u);
  EXPECT_EQ(accepted[0], 1u);
  // A gap breaks the chain.
  checker.update({});
  EXPECT_TRUE(checker.update({{13, 14}}).empty());
  // A group that jumps elsewhere starts over.
  EXPECT_TRUE(checker.update({{90}}).empty());
  EXPECT_TRUE(checker.update({{91, 90}}).empty());
  EXPECT_EQ(checker.update({{91}}).size(), 1u);
}

}  // namespace
}  // namespace kestrel::loop
