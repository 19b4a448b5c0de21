// A mover's box carried across the frames its detection misses (detect/box_coasting).
#include "detect/box_coasting.hpp"

#include <gtest/gtest.h>

namespace kestrel::detect {
namespace {

constexpr Timestamp kFrame = 33'333'333;  // 30 Hz

Detection box(const std::string& label, float x, float y, float w = 40, float h = 100) {
  Detection d;
  d.label = label;
  d.score = 0.8f;
  d.x_min = x;
  d.y_min = y;
  d.x_max = x + w;
  d.y_max = y + h;
  return d;
}

TEST(BoxCoasting, AMissedWalkerIsCarriedAlongItsMotionForMaxFrames) {
  BoxCoaster coaster;  // two frames
  EXPECT_TRUE(coaster.update(0, {box("person", 100, 50)}, 640, 480).empty());
  EXPECT_TRUE(coaster.update(kFrame, {box("person", 110, 50)}, 640, 480).empty());
  // Missed: where 10 px a frame puts it.
  auto carried = coaster.update(2 * kFrame, {}, 640, 480);
  ASSERT_EQ(carried.size(), 1u);
  EXPECT_EQ(carried[0].label, "person");
  EXPECT_NEAR(carried[0].x_min, 120.0f, 1e-3);
  EXPECT_NEAR(carried[0].x_max, 160.0f, 1e-3);
  EXPECT_NEAR(carried[0].y_min, 50.0f, 1e-3);
  carried = coaster.update(3 * kFrame, {}, 640, 480);
  ASSERT_EQ(carried.size(), 1u);
  EXPECT_NEAR(carried[0].x_min, 130.0f, 1e-3);
  // The third missed frame in a row: the walker may be gone.
  EXPECT_TRUE(coaster.update(4 * kFrame, {}, 640, 480).empty());
}

TEST(BoxCoasting, ADetectionAfterACarryContinuesTheTrack) {
  BoxCoaster coaster;
  coaster.update(0, {box("person", 100, 50)}, 640, 480);
  coaster.update(kFrame, {box("person", 110, 50)}, 640, 480);
  ASSERT_EQ(coaster.update(2 * kFrame, {}, 640, 480).size(), 1u);
  // Found again where it should be: no second box, one track, and its count of carried
  // frames starts over.
  EXPECT_TRUE(coaster.update(3 * kFrame, {box("person", 130, 50)}, 640, 480).empty());
  EXPECT_EQ(coaster.tracks(), 1u);
  auto carried = coaster.update(4 * kFrame, {}, 640, 480);
  ASSERT_EQ(carried.size(), 1u);
  EXPECT_NEAR(carried[0].x_min, 140.0f, 1e-3);  // 30 px over the two frames since frame 1
  EXPECT_EQ(coaster.update(5 * kFrame, {}, 640, 480).size(), 1u);
}

TEST(BoxCoasting, AOneFrameDetectionIsNotCarried) {
  BoxCoaster coaster;
  coaster.update(0, {box("person", 100, 50)}, 640, 480);
  EXPECT_TRUE(coaster.update(kFrame, {}, 640, 480).empty());
}

TEST(BoxCoasting, LabelsDoNotContinueEachOther) {
  BoxCoaster coaster;
  for (int k = 0; k < 3; ++k) {
    coaster.update(k * kFrame, {box("person", 100, 50), box("car", 100, 60)}, 640, 480);
  }
  // The person is still detected, on the car's place too: the car is carried all the same.
  const auto carried = coaster.update(3 * kFrame, {box("person", 100, 50)}, 640, 480);
  ASSERT_EQ(carried.size(), 1u);
  EXPECT_EQ(carried[0].label, "car");
}

TEST(BoxCoasting, CarriedBoxesStayInTheImageAndTracksEnd) {
  BoxCoaster coaster;
  coaster.update(0, {box("person", 570, 50, 60)}, 640, 480);
  coaster.update(kFrame, {box("person", 590, 50, 60)}, 640, 480);
  const auto carried = coaster.update(2 * kFrame, {}, 640, 480);
  ASSERT_EQ(carried.size(), 1u);
  EXPECT_NEAR(carried[0].x_min, 610.0f, 1e-3);
  EXPECT_NEAR(carried[0].x_max, 640.0f, 1e-3);  // clipped at the image's edge
  // Not detected for longer than forget_seconds: the track ends.
  coaster.update(from_seconds(1.0), {}, 640, 480);
  EXPECT_EQ(coaster.tracks(), 0u);
}

TEST(BoxCoasting, ZeroFramesIsOff) {
  BoxCoastOptions o;
  o.max_frames = 0;
  BoxCoaster coaster(o);
  coaster.update(0, {box("person", 100, 50)}, 640, 480);
  coaster.update(kFrame, {box("person", 110, 50)}, 640, 480);
  EXPECT_TRUE(coaster.update(2 * kFrame, {}, 640, 480).empty());
}

}  // namespace
}  // namespace kestrel::detect
