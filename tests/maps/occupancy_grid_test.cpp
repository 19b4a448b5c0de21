#include <gtest/gtest.h>

#include "maps/occupancy_grid.hpp"

using namespace kestrel;
using namespace kestrel::maps;

TEST(OccupancyGrid, CellOfAndCenterAreInverse) {
  OccupancyGrid g(20, 10, 0.1, Vec2(-1.0, 2.0), kFree);
  const auto c = g.cell_of(Vec2(-0.95, 2.05));
  ASSERT_TRUE(c);
  EXPECT_EQ(*c, (GridCell{0, 0}));
  const auto d = g.cell_of(Vec2(0.93, 2.97));
  ASSERT_TRUE(d);
  EXPECT_EQ(*d, (GridCell{19, 9}));
  EXPECT_NEAR(g.center_of(*d).x(), 0.95, 1e-12);
  EXPECT_NEAR(g.center_of(*d).y(), 2.95, 1e-12);
  EXPECT_FALSE(g.cell_of(Vec2(1.01, 2.5)));
  EXPECT_FALSE(g.cell_of(Vec2(0.0, 1.99)));
}
