#include "mapping/map.hpp"

#include <gtest/gtest.h>

#include <map>
#include <unordered_map>

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

// Keyframes 1..4 see the first 30 of keyframe 0's 40 points (at its pyramid level); keyframe 4
// also sees points of its own.
struct CullingScene {
  Map map;
  std::vector<KeyframeId> kf;
  CullingScene() {
    kf.push_back(map.add_keyframe(0, SE3(), grid_features(40, 2.0)));
    map.create_points_from_depth(kf[0], 40, 10.0);
    for (int k = 1; k <= 4; ++k) {
      kf.push_back(map.add_keyframe(k, SE3(), grid_features(40, 2.0)));
      for (int i = 0; i < 30; ++i) {
        map.add_observation(map.keyframe(kf[0])->point_of_feature[static_cast<std::size_t>(i)],
                            kf.back(), i);
      }
    }
    map.create_points_from_depth(kf[4], 40, 10.0);  // features 30..39 of keyframe 4
    for (KeyframeId id : kf) map.update_connections(id, 5);
  }
};

TEST(Map, RedundancyIsTheShareOfClosePointsOthersSeeAtTheSameScale) {
  CullingScene s;
  // Keyframe 0: 30 of 40 points seen by 4 others.
  EXPECT_DOUBLE_EQ(s.map.redundancy(s.kf[0], 10.0, 3), 30.0 / 40.0);
  // Keyframes 1..3: every point they see, 4 others see too.
  EXPECT_DOUBLE_EQ(s.map.redundancy(s.kf[1], 10.0, 3), 1.0);
  // Keyframe 4: its own 10 points no one else sees.
  EXPECT_DOUBLE_EQ(s.map.redundancy(s.kf[4], 10.0, 3), 30.0 / 40.0);
  // More observers than there are keyframes: nothing is redundant.
  EXPECT_DOUBLE_EQ(s.map.redundancy(s.kf[1], 10.0, 5), 0.0);
  // Far points do not count (grid_features' depths run from 2.0 to 2.39 m).
  EXPECT_DOUBLE_EQ(s.map.redundancy(s.kf[1], 1.0, 3), 0.0);
  // Seen only at a coarser level by the others, a point is not redundant.
  for (KeyframeId id : {s.kf[2], s.kf[3], s.kf[4]}) {
    for (auto& k : s.map.keyframe(id)->features.keypoints) k.level += 2;
  }
  EXPECT_DOUBLE_EQ(s.map.redundancy(s.kf[1], 10.0, 3), 0.0);
  EXPECT_DOUBLE_EQ(s.map.redundancy(s.kf.back() + 100, 10.0, 3), 0.0);  // no such keyframe
}

// The early-stopping test agrees with the share it stands for, at and around the boundary
// (keyframes 0 and 4: exactly 30 of 40).
TEST(Map, IsRedundantAgreesWithTheRedundancyShare) {
  CullingScene s;
  for (const int observers : {1, 3, 4, 5}) {
    for (const double max_depth : {1.0, 2.2, 10.0}) {
      for (KeyframeId id : s.kf) {
        const double share = s.map.redundancy(id, max_depth, observers);
        for (const double fraction : {0.0, 0.5, 0.74, 0.75, 0.76, 0.9, 1.0}) {
          EXPECT_EQ(s.map.is_redundant(id, max_depth, observers, fraction), share > fraction)
              << "keyframe " << id << ", observers " << observers << ", depth " << max_depth
              << ", fraction " << fraction << ", share " << share;
        }
      }
    }
  }
  EXPECT_FALSE(s.map.is_redundant(s.kf.back() + 100, 10.0, 3, 0.0));  // no such keyframe
}

// A point seen from more keyframes than kDescriptorViews takes its descriptor from the newest
// views: 20 old views say A, 20 new ones B (all 40 would tie, and the oldest would win).
TEST(Map, APointsDescriptorComesFromItsNewestViews) {
  Map map;
  auto one_feature = [](std::uint64_t word) {
    FrameFeatures f = grid_features(1, 2.0);
    f.descriptors[0].words = {word, 0, 0, 0};
    return f;
  };
  const std::uint64_t a = 0, b = ~std::uint64_t{0};
  const KeyframeId first = map.add_keyframe(0, SE3(), one_feature(a));
  map.create_points_from_depth(first, 1, 10.0);
  const PointId p = map.keyframe(first)->point_of_feature[0];
  for (int k = 1; k < 40; ++k) {
    const KeyframeId id = map.add_keyframe(k, SE3(), one_feature(k < 20 ? a : b));
    map.add_observation(p, id, 0);
  }
  map.update_point(p);
  ASSERT_EQ(map.point(p)->observations.size(), 40u);
  EXPECT_EQ(map.point(p)->descriptor.words[0], b);
}

// Erasing keyframe A, whose neighbour B had no other link as strong as min_shared: B (and C,
// linked to A alone) get their strongest remaining link back, and every weight is what a full
// recount gives, though only the keyframes left without links are recounted.
TEST(Map, ErasingAKeyframeRelinksTheNeighboursItLeavesAlone) {
  Map map;
  const KeyframeId a = map.add_keyframe(0, SE3(), grid_features(40, 2.0));
  map.create_points_from_depth(a, 40, 10.0);
  const KeyframeId b = map.add_keyframe(1, SE3(), grid_features(40, 2.0));
  const KeyframeId c = map.add_keyframe(2, SE3(), grid_features(40, 2.0));
  for (int i = 0; i < 30; ++i) {
    const PointId p = map.keyframe(a)->point_of_feature[static_cast<std::size_t>(i)];
    map.add_observation(p, b, i);
    if (i < 5) map.add_observation(p, c, i);
  }
  for (KeyframeId id : {a, b, c}) map.update_connections(id);
  ASSERT_EQ(map.keyframe(b)->connections, (mapping::FlatKeyframeMap{{a, 30}}));
  map.erase_keyframe(a);
  EXPECT_EQ(map.keyframe(b)->connections, (mapping::FlatKeyframeMap{{c, 5}}));
  EXPECT_EQ(map.keyframe(c)->connections, (mapping::FlatKeyframeMap{{b, 5}}));
  for (KeyframeId id : {b, c}) {
    const auto kept = map.keyframe(id)->connections;
    map.update_connections(id);
    EXPECT_EQ(map.keyframe(id)->connections, kept) << id;
  }
}

TEST(Map, ErasingAKeyframeRemovesItsObservationsEdgesAndLonePoints) {
  CullingScene s;
  ASSERT_TRUE(s.map.keyframe(s.kf[4])->connections.count(s.kf[2]));
  const std::size_t points = s.map.num_points();  // 40 of keyframe 0, 10 of keyframe 4
  ASSERT_EQ(points, 50u);
  s.map.erase_keyframe(s.kf[4]);
  EXPECT_EQ(s.map.keyframe(s.kf[4]), nullptr);
  EXPECT_EQ(s.map.num_keyframes(), 4u);
  EXPECT_EQ(s.map.num_points(), 40u);  // the 10 only keyframe 4 saw are gone
  for (const auto& [id, p] : s.map.points()) {
    EXPECT_FALSE(p.observations.count(s.kf[4])) << id;
    EXPECT_FALSE(p.observations.empty()) << id;
  }
  for (const auto& [id, k] : s.map.keyframes()) {
    EXPECT_FALSE(k.connections.count(s.kf[4])) << id;
    for (const auto& [other, w] : k.connections) {
      EXPECT_EQ(s.map.keyframe(other)->connections.at(id), w);  // symmetric
    }
  }
  // The shared points now have 3 other observers each: enough for 3, not for 4.
  EXPECT_DOUBLE_EQ(s.map.redundancy(s.kf[0], 10.0, 3), 30.0 / 40.0);
  EXPECT_DOUBLE_EQ(s.map.redundancy(s.kf[1], 10.0, 3), 1.0);
  EXPECT_DOUBLE_EQ(s.map.redundancy(s.kf[1], 10.0, 4), 0.0);
  s.map.erase_keyframe(s.kf[4]);  // twice: nothing happens
  EXPECT_EQ(s.map.num_keyframes(), 4u);
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

// A loaded map may carry any non-negative keyframe ids: a sparse one is tallied as well as a
// dense one (no table as long as the largest id).
TEST(Map, CovisibilityWithSparseKeyframeIds) {
  Map map;
  const KeyframeId k0 = map.add_keyframe(0, SE3(), grid_features(60, 2.0));
  map.create_points_from_depth(k0, 60, 10.0);
  const KeyframeId k1 = map.add_keyframe(1, SE3(), grid_features(60, 2.0));
  for (int i = 0; i < 40; ++i) map.add_observation(map.keyframe(k0)->point_of_feature[i], k1, i);
  constexpr KeyframeId kFar = 1'000'000'000'000;
  std::map<KeyframeId, Keyframe> keyframes = map.keyframes();
  Keyframe moved = keyframes.at(k1);
  moved.id = kFar;
  keyframes.erase(k1);
  keyframes.emplace(kFar, std::move(moved));
  std::unordered_map<PointId, MapPoint> points = map.points();
  for (auto& [id, p] : points) {
    if (auto it = p.observations.find(k1); it != p.observations.end()) {
      const int feature = it->second;
      p.observations.erase(it);
      p.observations[kFar] = feature;
    }
  }
  Map loaded;
  loaded.restore(std::move(keyframes), std::move(points));
  loaded.update_connections(kFar);
  EXPECT_EQ(loaded.keyframe(kFar)->connections.at(k0), 40);
  EXPECT_EQ(loaded.keyframe(k0)->connections.at(kFar), 40);
}

// Keyframes are found by id through an index into the map's own storage: a copy must find its
// own keyframes (not the original's), a moved map the same ones, and an erased or far-off id
// none or the right one.
TEST(Map, CopiesAndMovesFindTheirOwnKeyframes) {
  Map map;
  for (int k = 0; k < 5; ++k) map.add_keyframe(k, SE3(), grid_features(20, 2.0));
  map.erase_keyframe(2);
  Map copy = map;
  for (KeyframeId k : {0, 1, 3, 4}) {
    ASSERT_NE(copy.keyframe(k), nullptr);
    EXPECT_NE(copy.keyframe(k), map.keyframe(k));
    EXPECT_EQ(copy.keyframe(k)->id, k);
  }
  EXPECT_EQ(copy.keyframe(2), nullptr);
  EXPECT_EQ(copy.keyframe(5), nullptr);
  EXPECT_EQ(copy.keyframe(-1), nullptr);
  copy.keyframe(3)->t = 42;
  EXPECT_EQ(map.keyframe(3)->t, 3);

  Map assigned;
  assigned.add_keyframe(0, SE3(), grid_features(5, 1.0));
  assigned = copy;
  EXPECT_EQ(assigned.keyframe(3)->t, 42);
  EXPECT_NE(assigned.keyframe(3), copy.keyframe(3));

  const Keyframe* before = copy.keyframe(4);
  Map moved = std::move(copy);
  EXPECT_EQ(moved.keyframe(4), before);
  const KeyframeId next = moved.add_keyframe(9, SE3(), grid_features(5, 1.0));
  EXPECT_EQ(next, 5);
  EXPECT_EQ(moved.keyframe(next)->t, 9);

  // Restored with ids far beyond the keyframe count: found all the same.
  std::map<KeyframeId, Keyframe> keyframes;
  constexpr KeyframeId kFar = 1'000'000'000'000;
  keyframes[kFar].id = kFar;
  keyframes[7].id = 7;
  Map loaded;
  loaded.restore(std::move(keyframes), {});
  ASSERT_NE(loaded.keyframe(kFar), nullptr);
  EXPECT_EQ(loaded.keyframe(kFar)->id, kFar);
  EXPECT_EQ(loaded.keyframe(7)->id, 7);
  EXPECT_EQ(loaded.keyframe(8), nullptr);
  EXPECT_EQ(loaded.add_keyframe(1, SE3(), grid_features(5, 1.0)), kFar + 1);
  EXPECT_NE(loaded.keyframe(kFar + 1), nullptr);
}

}  // namespace
}  // namespace kestrel::mapping
