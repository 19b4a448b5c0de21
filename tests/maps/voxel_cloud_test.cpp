#include <gtest/gtest.h>

#include "maps/voxel_cloud.hpp"

using namespace kestrel::maps;

TEST(VoxelCloud, AveragesPointsAndVotesTheLabel) {
  VoxelCloud c(0.1);
  c.add({0.01f, 0.01f, 0.01f}, 10, 20, 30, 5);
  c.add({0.03f, 0.05f, 0.07f}, 30, 40, 50, 5);
  c.add({0.05f, 0.03f, 0.02f}, 20, 30, 40, 7);
  c.add({0.25f, 0.0f, 0.0f}, 0, 0, 0, 0);
  ASSERT_EQ(c.size(), 2u);
  for (const CloudPoint& p : c.points()) {
    if (p.p.x() > 0.2f) continue;
    EXPECT_NEAR(p.p.x(), 0.03f, 1e-6);
    EXPECT_NEAR(p.p.y(), 0.03f, 1e-6);
    EXPECT_EQ(p.r, 20);
    EXPECT_EQ(p.b, 40);
    EXPECT_EQ(p.label, 5);
  }
  c.filter([](const Eigen::Vector3f& p) { return p.x() < 0.2f; });
  EXPECT_EQ(c.size(), 1u);
}

TEST(VoxelCloud, NegativeCoordinatesGetTheirOwnVoxels) {
  VoxelCloud c(0.1);
  c.add({-0.05f, 0.0f, 0.0f}, 0, 0, 0, 0);
  c.add({0.05f, 0.0f, 0.0f}, 0, 0, 0, 0);
  c.add({0.05f, -0.05f, 0.0f}, 0, 0, 0, 0);
  EXPECT_EQ(c.size(), 3u);
}
