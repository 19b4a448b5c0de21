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

// A car seen end-on from close by and side-on from afar: a dense short leg and a sparse long
// one. The box must follow the car's sides, not the L's diagonal (where the smallest trimmed
// footprint lies), and span both legs.
TEST(UprightBox, LShapeOfACarSeenFromTwoSidesKeepsItsAxes) {
  std::mt19937 rng(5);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float yaw = 0.5f, c = std::cos(yaw), s = std::sin(yaw);
  std::vector<Eigen::Vector3f> pts;
  auto add = [&](float a, float b) {
    pts.emplace_back(c * a - s * b + noise(rng), s * a + c * b + noise(rng), 0.2f + u(rng));
  };
  for (int i = 0; i < 4000; ++i) add(u(rng) * 1.8f - 0.9f, -2.0f);  // the end, close by
  for (int i = 0; i < 1200; ++i) add(-0.9f, u(rng) * 4.0f - 2.0f);  // the side, far away
  const UprightBox box = fit_upright_box(pts);
  // The long side is reported along the yaw axis: the car's side runs along b (yaw + 90 deg).
  EXPECT_NEAR(std::remainder(box.yaw - (yaw + M_PI / 2), M_PI), 0.0, 0.03);
  // The 2% trim eats about 0.35 m of the sparse leg's tip (104 of its 1200 points).
  EXPECT_NEAR(box.size.x(), 4.0, 0.4);
  EXPECT_NEAR(box.size.y(), 1.8, 0.1);
}
