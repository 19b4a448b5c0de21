#include <gtest/gtest.h>

#include <random>

#include "nav/astar_planner.hpp"
#include "nav/inflation.hpp"

using namespace kestrel;
using namespace kestrel::nav;
using namespace kestrel::maps;

namespace {

// 10 m x 6 m room at 0.1 m, a wall at x = 5 m with a 1 m gap at the top.
OccupancyGrid room_with_wall() {
  OccupancyGrid g(100, 60, 0.1, Vec2::Zero(), kFree);
  for (int y = 0; y < 60; ++y) {
    g.set({0, y}, kOccupied);
    g.set({99, y}, kOccupied);
  }
  for (int x = 0; x < 100; ++x) {
    g.set({x, 0}, kOccupied);
    g.set({x, 59}, kOccupied);
  }
  for (int y = 0; y < 48; ++y) g.set({50, y}, kOccupied);
  return g;
}

bool path_is_collision_free(const OccupancyGrid& g, const PlanResult& r) {
  for (std::size_t k = 0; k < r.cells.size(); ++k) {
    if (g.at(r.cells[k]) != kFree) return false;
    if (k > 0) {
      const int dx = std::abs(r.cells[k].x - r.cells[k - 1].x);
      const int dy = std::abs(r.cells[k].y - r.cells[k - 1].y);
      if (dx > 1 || dy > 1) return false;
    }
  }
  return true;
}

}  // namespace

TEST(AStar, StraightLineInAnEmptyRoom) {
  OccupancyGrid g(50, 50, 0.1, Vec2::Zero(), kFree);
  const PlanResult r = plan_path(g, Vec2(0.55, 0.55), Vec2(4.05, 0.55));
  ASSERT_TRUE(r.ok()) << r.message;
  EXPECT_NEAR(r.length, 3.5, 1e-9);
  EXPECT_EQ(r.cells.size(), 36u);
  const PlanResult d = plan_path(g, Vec2(0.05, 0.05), Vec2(2.05, 2.05));
  ASSERT_TRUE(d.ok());
  EXPECT_NEAR(d.length, 20 * 0.1 * std::sqrt(2.0), 1e-9);
}

TEST(AStar, GoesThroughTheGapAndStaysClearOfTheInflatedWall) {
  const OccupancyGrid g = room_with_wall();
  PlannerOptions opt;
  opt.robot_radius = 0.3;
  const PlanResult r = plan_path(g, Vec2(2.0, 1.0), Vec2(8.0, 1.0), opt);
  ASSERT_TRUE(r.ok()) << r.message;
  const OccupancyGrid inflated = inflate(g, 0.3);
  EXPECT_TRUE(path_is_collision_free(inflated, r));
  double max_y = 0;
  for (const auto& p : r.waypoints) max_y = std::max(max_y, p.y());
  EXPECT_GT(max_y, 4.8);      // it had to use the gap
  EXPECT_GT(r.length, 10.0);  // the straight line is 6 m
}

TEST(AStar, GoalInsideAnObstacleIsAClearError) {
  const OccupancyGrid g = room_with_wall();
  const PlanResult r = plan_path(g, Vec2(2.0, 1.0), Vec2(5.05, 2.0));
  EXPECT_EQ(r.status, PlanStatus::kGoalBlocked);
  EXPECT_NE(r.message.find("inside an obstacle"), std::string::npos) << r.message;
  EXPECT_TRUE(r.cells.empty());
  PlannerOptions opt;
  opt.robot_radius = 0.3;
  const PlanResult near = plan_path(g, Vec2(2.0, 1.0), Vec2(5.3, 2.0), opt);
  EXPECT_EQ(near.status, PlanStatus::kGoalBlocked);
  EXPECT_NE(near.message.find("robot radius"), std::string::npos) << near.message;
}

TEST(AStar, OutsideAndUnreachableAreReported) {
  OccupancyGrid g = room_with_wall();
  EXPECT_EQ(plan_path(g, Vec2(-1, 1), Vec2(2, 2)).status, PlanStatus::kStartOutside);
  EXPECT_EQ(plan_path(g, Vec2(2, 2), Vec2(20, 2)).status, PlanStatus::kGoalOutside);
  for (int y = 48; y < 60; ++y) g.set({50, y}, kOccupied);  // close the gap
  const PlanResult r = plan_path(g, Vec2(2.0, 1.0), Vec2(8.0, 1.0));
  EXPECT_EQ(r.status, PlanStatus::kUnreachable);
  EXPECT_NE(r.message.find("cannot be reached"), std::string::npos);
  g.set({20, 10}, kUnknown);
  EXPECT_EQ(plan_path(g, Vec2(2.05, 1.05), Vec2(3, 3)).status, PlanStatus::kStartBlocked);
}

TEST(AStar, NoCornerCuttingBetweenDiagonalObstacles) {
  OccupancyGrid g(3, 3, 1.0, Vec2::Zero(), kFree);
  g.set({1, 0}, kOccupied);
  g.set({0, 1}, kOccupied);
  g.set({1, 2}, kOccupied);
  g.set({2, 1}, kOccupied);
  EXPECT_EQ(plan_path(g, Vec2(0.5, 0.5), Vec2(1.5, 1.5)).status, PlanStatus::kUnreachable);
}

TEST(AStar, MatchesDijkstraLengthOnRandomGrids) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    OccupancyGrid g(30, 30, 1.0, Vec2::Zero(), kFree);
    std::bernoulli_distribution obstacle(0.25);
    for (auto& c : g.cells()) c = obstacle(rng) ? kOccupied : kFree;
    g.set({0, 0}, kFree);
    g.set({29, 29}, kFree);
    // Dijkstra over the same move set (8-connected, no corner cutting).
    std::vector<double> dist(900, 1e18);
    std::vector<bool> done(900, false);
    dist[0] = 0;
    for (int it = 0; it < 900; ++it) {
      int best = -1;
      for (int i = 0; i < 900; ++i)
        if (!done[i] && (best < 0 || dist[i] < dist[best])) best = i;
      if (dist[best] >= 1e17) break;
      done[best] = true;
      const int x = best % 30, y = best / 30;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          if (!dx && !dy) continue;
          const GridCell n{x + dx, y + dy};
          if (!g.contains(n) || g.at(n) != kFree) continue;
          if (dx && dy && (g.at({x + dx, y}) != kFree || g.at({x, y + dy}) != kFree)) continue;
          const double c = dist[best] + ((dx && dy) ? std::sqrt(2.0) : 1.0);
          dist[g.index(n)] = std::min(dist[g.index(n)], c);
        }
    }
    const PlanResult r = plan_path(g, Vec2(0.5, 0.5), Vec2(29.5, 29.5));
    if (dist[899] >= 1e17) {
      EXPECT_EQ(r.status, PlanStatus::kUnreachable);
    } else {
      ASSERT_TRUE(r.ok()) << r.message;
      EXPECT_NEAR(r.length, dist[899], 1e-9) << "trial " << trial;
      EXPECT_TRUE(path_is_collision_free(g, r));
    }
  }
}
