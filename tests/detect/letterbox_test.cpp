#include <gtest/gtest.h>

#include "detect/letterbox.hpp"

namespace kestrel::detect {
namespace {

TEST(Letterbox, WideImageIsPaddedTopAndBottom) {
  const Letterbox lb = Letterbox::make(640, 480, 320, 320, InputResize::kLetterbox);
  EXPECT_EQ(lb.resized_width, 320);
  EXPECT_EQ(lb.resized_height, 240);
  EXPECT_EQ(lb.pad_x, 0);
  EXPECT_EQ(lb.pad_y, 40);
  // A known box: image (100, 80)-(300, 280) lies at (50, 80)-(150, 180) in the network input.
  EXPECT_DOUBLE_EQ(lb.to_net_x(100), 50);
  EXPECT_DOUBLE_EQ(lb.to_net_y(80), 80);
  EXPECT_DOUBLE_EQ(lb.to_net_x(300), 150);
  EXPECT_DOUBLE_EQ(lb.to_net_y(280), 180);
  // And maps back exactly.
  EXPECT_DOUBLE_EQ(lb.to_image_x(50), 100);
  EXPECT_DOUBLE_EQ(lb.to_image_y(80), 80);
  EXPECT_DOUBLE_EQ(lb.to_image_x(150), 300);
  EXPECT_DOUBLE_EQ(lb.to_image_y(180), 280);
  // The padding itself maps outside the image.
  EXPECT_LT(lb.to_image_y(0), 0);
  EXPECT_GT(lb.to_image_y(320), 480);
}

TEST(Letterbox, TallImageAndDarknetIntegerSizes) {
  // 375 * 416 / 500 = 311.99 -> Darknet's integer division gives 311, centred with pad 52.
  const Letterbox wide = Letterbox::make(500, 375, 416, 416, InputResize::kLetterbox);
  EXPECT_EQ(wide.resized_width, 416);
  EXPECT_EQ(wide.resized_height, 312);
  EXPECT_EQ(wide.pad_y, 52);
  const Letterbox tall = Letterbox::make(333, 500, 320, 320, InputResize::kLetterbox);
  EXPECT_EQ(tall.resized_height, 320);
  EXPECT_EQ(tall.resized_width, 213);  // 333 * 320 / 500 = 213.1
  EXPECT_EQ(tall.pad_x, 53);
  EXPECT_EQ(tall.pad_y, 0);
  for (double x : {0.0, 17.5, 166.0, 333.0}) {
    EXPECT_NEAR(tall.to_image_x(tall.to_net_x(x)), x, 1e-9);
  }
}

TEST(Letterbox, StretchUsesTheWholeInput) {
  const Letterbox lb = Letterbox::make(768, 576, 320, 320, InputResize::kStretch);
  EXPECT_EQ(lb.pad_x, 0);
  EXPECT_EQ(lb.pad_y, 0);
  EXPECT_DOUBLE_EQ(lb.to_image_x(320), 768);
  EXPECT_DOUBLE_EQ(lb.to_image_y(160), 288);
  EXPECT_DOUBLE_EQ(lb.to_net_x(384), 160);
}

TEST(Letterbox, RejectsEmptySizes) {
  EXPECT_THROW(Letterbox::make(0, 10, 320, 320, InputResize::kLetterbox), std::invalid_argument);
  EXPECT_THROW(Letterbox::make(10, 10, 320, -1, InputResize::kStretch), std::invalid_argument);
}

}  // namespace
}  // namespace kestrel::detect
