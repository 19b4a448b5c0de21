#include <gtest/gtest.h>

#include "semantic/euclidean_clusters.hpp"

using namespace kestrel::semantic;

TEST(EuclideanClusters, SeparatesSurfacesFartherThanTheTolerance) {
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) {
      pts.emplace_back(0.02f * i, 0.02f * j, 1.0f);  // a plate at 1 m
      pts.emplace_back(0.02f * i, 0.02f * j, 1.3f);  // one 30 cm behind
    }
  pts.emplace_back(5.0f, 5.0f, 5.0f);  // a lone outlier
  const auto c = euclidean_clusters(pts, 0.05f, 10);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[0].size(), 400u);
  EXPECT_EQ(c[1].size(), 400u);
  for (const auto& cl : c) {
    const float z = pts[cl.front()].z();
    for (int i : cl) EXPECT_EQ(pts[i].z(), z);
  }
}

TEST(EuclideanClusters, ChainsOfTouchingPointsStayOneCluster) {
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 100; ++i) pts.emplace_back(0.04f * i, 0.0f, 0.0f);  // a 4 m rod
  const auto c = euclidean_clusters(pts, 0.05f, 1);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].size(), 100u);
}
