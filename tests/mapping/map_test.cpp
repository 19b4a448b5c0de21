#include "mapping/map.hpp"

#include <gtest/gtest.h>

namespace kestrel::mapping {
namespace {

// A keyframe's worth of features: n points on a grid at the given depth, all with depth.
FrameFeatures grid_features(int n, double z) {
  FrameFeatures f;
  f.width = 640;
  f.height = 480;
  for (int i = 0; i < n; ++i) {
    tracking::Keypoint k;
    k.px = k.un = Vec2(20.0 + (i % 20) * 30.0, 20.0 + (i / 20) * 30.0);
    k.level = i % 3;
    f.keypoints.push_back(k);
    OrbDescriptor d;
    d.words = {static_cast<std::uint64_t>(i), 0, 0, 0};
    f.descriptors.push_back(d);
    f.depth.push_back(z + 0.01 * i);
    f.points_c.push_back(Vec3((k.px.x() - 320) / 500 * f.depth.back(),
                              (k.px.y() - 240) / 500 * f.depth.back(), f.depth.back()));
    f.status.push_back(tracking::FeatureStatus::kStatic);
  }
  return f;
}

TEST(Map, CreatesPointsFromDepthNearestFirstInWorldFrame) {
  Map map;
  const SE3 T_w_c(SO3::exp(Vec3(0.1, -0.2, 0.05)), Vec3(1, 2, 3));
  FrameFeatures f = grid_features(100, 1.0);
  f.depth[5] = 0.0;  // a hole
  f.status[6] = tracking::FeatureStatus::kDynamic;
  const KeyframeId kf = map.add_keyframe(0, T_w_c, f);
  EXPECT_EQ(map.create_points_from_depth(kf, 50, 10.0), 50);
  EXPECT_EQ(map.num_points(), 50u);
  const Keyframe& k = *map.keyframe(kf);
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (i == 5 || i == 6) {
      EXPECT_EQ(k.point_of_feature[i], kNoPoint);
    }
    if (k.point_of_feature[i] == kNoPoint) continue;
    const MapPoint& p = *map.point(k.point_of_feature[i]);
    EXPECT_LT((p.p_w - T_w_c * f.points_c[i]).norm(), 1e-12);
    EXPECT_EQ(p.descriptor, f.descriptors[i]);
    EXPECT_GT(p.max_distance, p.min_distance);
    EXPECT_GT(p.normal.dot(T_w_c.rotation().col(2)), 0.5);
  }
  // Nearest first: the 50 points created are features 0..51 minus the hole and the dynamic one.
  EXPECT_NE(k.point_of_feature[0], kNoPoint);
  EXPECT_EQ(k.point_of_feature[99], kNoPoint);
  // Further calls only fill features that have no point yet.
  EXPECT_EQ(map.create_points_from_depth(kf, 1000, 10.0), 48);
  EXPECT_EQ(map.create_points_from_depth(kf, 1000, 10.0), 0);
}

TEST(Map, CullsPointsSeenByTooFewKeyframes) {
  Map map;
  const KeyframeId k0 = map.add_keyframe(0, SE3(), grid_features(40, 2.0));
  map.create_points_from_depth(k0, 40, 10.0);
  const KeyframeId k1 = map.add_keyframe(1, SE3(), grid_features(40, 2.0));
  const KeyframeId k2 = map.add_keyframe(2, SE3(), grid_features(40, 2.0));
  // Points 0..19 are re-observed in k1 and k2; 20..39 never again.
  for (int i = 0; i < 20; ++i) {
    const PointId p = map.keyframe(k0)->point_of_feature[static_cast<std::size_t>(i)];
    map.add_observation(p, k1, i);
    map.add_observation(p, k2, i);
  }
  // Point 0 was predicted in view many times but rarely matched.
  map.point(map.keyframe(k0)->point_of_feature[0])->visible = 20;
  EXPECT_EQ(map.cull_points(k1), 1);  // only the low found-ratio one before two keyframes pass
  EXPECT_EQ(map.cull_points(k2), 20);
  EXPECT_EQ(map.num_points(), 19u);
  for (const auto& [id, p] : map.points()) EXPECT_EQ(p.observations.size(), 3u);
  EXPECT_EQ(map.keyframe(k0)->point_of_feature[25], kNoPoint);
}

TEST(Map, CovisibilityCountsSharedPoints) {
  Map map;
  const KeyframeId k0 = map.add_keyframe(0, SE3(), grid_features(60, 2.0));
  map.create_points_from_depth(k0, 60, 10.0);
  const KeyframeId k1 = map.add_keyframe(1, SE3(), grid_features(60, 2.0));
  const KeyframeId k2 = map.add_keyframe(2, SE3(), grid_features(60, 2.0));
  for (int i = 0; i < 40; ++i) map.add_observation(map.keyframe(k0)->point_of_feature[i], k1, i);
  for (int i = 0; i < 20; ++i) map.add_observation(map.keyframe(k0)->point_of_feature[i], k2, i);
  map.update_connections(k1);
  map.update_connections(k2);
  EXPECT_EQ(map.keyframe(k1)->connections.at(k0), 40);
  EXPECT_EQ(map.keyframe(k0)->connections.at(k1), 40);
  EXPECT_EQ(map.keyframe(k2)->connections.at(k1), 20);
  EXPECT_EQ(map.covisible(k0, 1), std::vector<KeyframeId>{k1});
  EXPECT_EQ(map.tracked_points(k0, 2), 40);
  EXPECT_EQ(map.tracked_points(k0, 3), 20);
  // Erasing the last observation of a point erases the point.
  const PointId p59 = map.keyframe(k0)->point_of_feature[59];
  map.erase_observation(p59, k0);
  EXPECT_EQ(map.point(p59), nullptr);
}

}  // namespace
}  // namespace kestrel::mapping
