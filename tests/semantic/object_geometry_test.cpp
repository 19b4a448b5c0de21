#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "semantic/object_geometry.hpp"

using namespace kestrel::semantic;

TEST(UprightBox, RecoversCentreSizeAndYawOfARotatedBox) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-0.5f, 0.5f);
  const float yaw = 0.4f, c = std::cos(yaw), s = std::sin(yaw);
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 20000; ++i) {
    const float a = u(rng) * 1.2f, b = u(rng) * 0.6f, z = 0.4f + u(rng) * 0.8f;
    pts.emplace_back(2.0f + c * a - s * b, -1.0f + s * a + c * b, z);
  }
  const UprightBox box = fit_upright_box(pts, 0.0);
  EXPECT_NEAR(box.center.x(), 2.0, 0.01);
  EXPECT_NEAR(box.center.y(), -1.0, 0.01);
  EXPECT_NEAR(box.center.z(), 0.4, 0.01);
  EXPECT_NEAR(box.size.x(), 1.2, 0.02);
  EXPECT_NEAR(box.size.y(), 0.6, 0.02);
  EXPECT_NEAR(box.size.z(), 0.8, 0.02);
  EXPECT_NEAR(box.yaw, 0.4, 0.02);
}

TEST(UprightBox, TrimmingIgnoresOutliers) {
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i <= 100; ++i) pts.emplace_back(0.01f * i, 0.0f, 0.0f);
  pts.emplace_back(10.0f, 0.0f, 0.0f);
  EXPECT_NEAR(fit_upright_box(pts, 0.02).size.x(), 0.97, 0.03);
  EXPECT_NEAR(fit_upright_box(pts, 0.0).size.x(), 10.0, 1e-5);
}
