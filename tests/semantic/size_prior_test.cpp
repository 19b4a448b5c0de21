#include <gtest/gtest.h>

#include <cmath>

#include "semantic/size_prior.hpp"

using namespace kestrel;
using namespace kestrel::semantic;

namespace {

UprightBox box_at(double x, double y, double sx, double sy, double yaw = 0.0) {
  UprightBox b;
  b.center = Vec3(x, y, 0.5);
  b.size = Vec3(sx, sy, 1.0);
  b.yaw = yaw;
  return b;
}

}  // namespace

// A chair seen only from behind, by cameras all on its -x side: its backrest is 0.2 m deep.
// The far side grows to the class's typical depth, away from the cameras; the near face stays.
TEST(SizePrior, ChairSeenFromBehindGrowsAwayFromTheCameras) {
  const auto prior = footprint_prior("chair");
  ASSERT_TRUE(prior);
  const UprightBox seen = box_at(2.0, 0.0, 0.46, 0.2, M_PI / 2);  // long side along y
  const UprightBox out = complete_with_prior(
      seen, {Vec3(-3, -1, 1.4), Vec3(-4, 0.5, 1.4), Vec3(-3.5, 2, 1.4)}, *prior);
  // Extents along world x and y, whichever side the box reports as its length.
  const bool along_x = std::abs(std::cos(out.yaw)) > 0.5;
  const double x_extent = along_x ? out.size.x() : out.size.y();
  const double y_extent = along_x ? out.size.y() : out.size.x();
  const double near_face = 2.0 - 0.1;
  EXPECT_NEAR(out.center.x() - x_extent / 2, near_face, 1e-9);
  EXPECT_NEAR(x_extent, prior->length, 1e-9);
  EXPECT_NEAR(y_extent, 0.46, 1e-9);  // seen whole across
  EXPECT_NEAR(out.center.y(), 0.0, 1e-9);
  EXPECT_DOUBLE_EQ(out.size.z(), 1.0);
}

// A car seen end-on (1.8 m across, its tail a few centimetres deep) must be a car's length
// deep; seen side-on (3.2 m along, 1.8 m deep) it is already a car's width deep: unchanged.
TEST(SizePrior, CarSeenEndOnGetsALengthSideOnKeepsItsDepth) {
  const auto prior = footprint_prior("car");
  ASSERT_TRUE(prior);
  const UprightBox tail = box_at(10.0, 0.0, 1.8, 0.3, M_PI / 2);  // 1.8 m along y, 0.3 m in x
  const UprightBox a = complete_with_prior(tail, {Vec3(4, 0, 0.5), Vec3(5, 0.4, 0.5)}, *prior);
  EXPECT_NEAR(a.size.x(), prior->length, 1e-9);
  EXPECT_NEAR(a.size.y(), 1.8, 1e-9);
  EXPECT_NEAR(a.center.x(), 10.0 - 0.15 + prior->length / 2, 1e-9);
  EXPECT_NEAR(std::abs(a.yaw), 0.0, 1e-9);

  const UprightBox side = box_at(10.0, 0.0, 3.2, 1.8);  // along x; cameras at -y
  const UprightBox b = complete_with_prior(side, {Vec3(8, -5, 0.5), Vec3(12, -5, 0.5)}, *prior);
  EXPECT_NEAR(b.size.x(), 3.2, 1e-9);  // the length was viewed along its whole side
  EXPECT_NEAR(b.size.y(), 1.8, 1e-9);
  EXPECT_NEAR(b.center.x(), 10.0, 1e-9);
  EXPECT_NEAR(b.center.y(), 0.0, 1e-9);
}

// A sofa along x, seen by cameras on its -x side, always cut by the image border on its -x
// end: the end away from the cameras was seen, so the sofa grows past the border (-x), not away
// from the cameras; cut across the axis instead, the hint does not apply.
TEST(SizePrior, CutByTheImageBorderGrowsPastTheBorder) {
  const auto prior = footprint_prior("couch");
  ASSERT_TRUE(prior);
  const UprightBox seen = box_at(-0.6, 4.4, 1.2, 0.9);  // x from -1.2 to 0.0
  const std::vector<Vec3> cameras = {Vec3(-4.5, -1.0, 1.4), Vec3(-4.6, 0.0, 1.4)};
  const UprightBox away = complete_with_prior(seen, cameras, *prior);
  EXPECT_NEAR(away.center.x() - away.size.x() / 2, -1.2, 1e-9);  // grew towards +x
  const UprightBox past = complete_with_prior(seen, cameras, *prior, Vec2(-0.8, 0.6));
  EXPECT_NEAR(past.size.x(), prior->length, 1e-9);
  EXPECT_NEAR(past.center.x() + past.size.x() / 2, 0.0, 1e-9);  // the seen end stays
  const UprightBox across = complete_with_prior(seen, cameras, *prior, Vec2(-0.3, 0.95));
  EXPECT_NEAR(across.center.x(), away.center.x(), 1e-9);
}

// Seen from one corner only, both far faces were hidden: the longer measured side gets the
// prior's length, the other its width.
TEST(SizePrior, CornerViewCompletesBothSides) {
  const auto prior = footprint_prior("car");
  ASSERT_TRUE(prior);
  const UprightBox corner = box_at(0.0, 0.0, 3.0, 1.2);
  const UprightBox out = complete_with_prior(corner, {Vec3(-4, -3, 0.5)}, *prior);
  EXPECT_NEAR(out.size.x(), prior->length, 1e-9);
  EXPECT_NEAR(out.size.y(), prior->width, 1e-9);
  EXPECT_NEAR(out.center.x(), (prior->length - 3.0) / 2, 1e-9);
  EXPECT_NEAR(out.center.y(), (prior->width - 1.2) / 2, 1e-9);
}

// Views from both sides, or from above the box's extent, measured it: nothing changes, and
// nothing is ever shrunk to the prior.
TEST(SizePrior, SeenFromBothSidesOrLargerThanThePriorIsUnchanged) {
  const auto prior = footprint_prior("chair");
  ASSERT_TRUE(prior);
  const UprightBox thin = box_at(0.0, 0.0, 0.45, 0.2);
  const UprightBox both = complete_with_prior(thin, {Vec3(0, -3, 1), Vec3(0, 3, 1)}, *prior);
  EXPECT_NEAR(both.size.y(), 0.2, 1e-9);
  EXPECT_NEAR(both.center.y(), 0.0, 1e-9);
  const UprightBox big = box_at(0.0, 0.0, 0.9, 0.7);
  const UprightBox out = complete_with_prior(big, {Vec3(-3, 0, 1)}, *prior);
  EXPECT_NEAR(out.size.x(), 0.9, 1e-9);
  EXPECT_NEAR(out.size.y(), 0.7, 1e-9);
  EXPECT_NEAR(out.center.x(), 0.0, 1e-9);
  EXPECT_TRUE(complete_with_prior(thin, {}, *prior).center.isApprox(thin.center));
}

TEST(SizePrior, OnlyClassesWithABoundedSize) {
  EXPECT_TRUE(footprint_prior("car"));
  EXPECT_TRUE(footprint_prior("dining table"));
  EXPECT_FALSE(footprint_prior("tv"));
  EXPECT_FALSE(footprint_prior("potted plant"));
  EXPECT_FALSE(footprint_prior("person"));
  EXPECT_FALSE(footprint_prior(""));
}
