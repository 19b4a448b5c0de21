#include "loop/place_view.hpp"

#include <gtest/gtest.h>

namespace kestrel::loop {
namespace {

// Four features: static with depth, dynamic with depth, static without depth, dynamic without.
tracking::FrameFeatures four_features() {
  tracking::FrameFeatures f;
  for (int i = 0; i < 4; ++i) {
    tracking::Keypoint k;
    k.px = Vec2(10.0 * i, 20.0 * i);
    k.un = Vec2(10.0 * i + 0.5, 20.0 * i + 0.5);
    f.keypoints.push_back(k);
    tracking::OrbDescriptor d;
    d.words[0] = static_cast<std::uint64_t>(i + 1);
    f.descriptors.push_back(d);
    const double z = i < 2 ? 2.0 + i : 0.0;
    f.depth.push_back(z);
    f.points_c.push_back(z > 0.0 ? Vec3(0.1 * i, 0.2, z) : Vec3::Zero());
    f.status.push_back(i % 2 == 0 ? tracking::FeatureStatus::kStatic
                                  : tracking::FeatureStatus::kDynamic);
  }
  return f;
}

TEST(PlaceView, HoldsTheStaticFeaturesOnlyWithTheirPointsAndPixels) {
  const tracking::FrameFeatures f = four_features();
  const PlaceView v = place_view(7, f, {3, 5});
  EXPECT_EQ(v.id, 7);
  EXPECT_EQ(v.neighbours, (std::vector<KeyframeId>{3, 5}));
  ASSERT_EQ(v.descriptors.size(), 2u);
  ASSERT_EQ(v.keypoints_un.size(), 2u);
  ASSERT_EQ(v.points_c.size(), 2u);
  ASSERT_EQ(v.has_point.size(), 2u);
  EXPECT_EQ(v.descriptors[0], f.descriptors[0]);
  EXPECT_EQ(v.descriptors[1], f.descriptors[2]);
  EXPECT_EQ(v.keypoints_un[1], f.keypoints[2].un);
  EXPECT_EQ(v.has_point[0], 1);
  EXPECT_EQ(v.has_point[1], 0);
  EXPECT_EQ(v.points_c[0], f.points_c[0]);
}

TEST(PlaceView, FeaturesWithoutStatusesAreAllKept) {
  tracking::FrameFeatures f = four_features();
  f.status.clear();
  EXPECT_EQ(place_view(1, f, {}).descriptors.size(), 4u);
}

}  // namespace
}  // namespace kestrel::loop
