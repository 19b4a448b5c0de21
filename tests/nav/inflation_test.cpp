#include <gtest/gtest.h>

#include <algorithm>

#include "nav/inflation.hpp"

using namespace kestrel;
using namespace kestrel::maps;
using kestrel::nav::inflate;

TEST(Inflation, GrowsObstaclesByTheRadius) {
  OccupancyGrid g(41, 41, 0.05, Vec2::Zero(), kFree);
  g.set({20, 20}, kOccupied);
  const OccupancyGrid in = inflate(g, 0.25);  // 5 cells
  EXPECT_TRUE(in.is_occupied({25, 20}));
  EXPECT_TRUE(in.is_occupied({20, 15}));
  EXPECT_FALSE(in.is_occupied({26, 20}));
  EXPECT_TRUE(in.is_occupied({23, 24}));   // 3-4-5: exactly on the circle
  EXPECT_FALSE(in.is_occupied({24, 24}));  // 5.66 cells away
  int count = 0;
  for (auto v : in.cells()) count += v >= 65;
  EXPECT_EQ(count, 81);  // lattice points with x^2 + y^2 <= 25
}

TEST(Inflation, AFilledBlockMatchesPerCellDiscs) {
  // The interior shortcut must not lose coverage.
  OccupancyGrid g(30, 30, 0.1, Vec2::Zero(), kFree);
  for (int y = 10; y < 20; ++y)
    for (int x = 10; x < 20; ++x) g.set({x, y}, kOccupied);
  const OccupancyGrid in = inflate(g, 0.3);
  for (int y = 0; y < 30; ++y) {
    for (int x = 0; x < 30; ++x) {
      const int dx = std::max({10 - x, 0, x - 19}), dy = std::max({10 - y, 0, y - 19});
      EXPECT_EQ(in.is_occupied({x, y}), dx * dx + dy * dy <= 9) << x << "," << y;
    }
  }
}
