#include "mapping/triangulation.hpp"

#include <gtest/gtest.h>

#include <random>

namespace kestrel::mapping {
namespace {

// Three keyframes 0.5 m apart along x, looking down +z, see: anchors 3 m away with depth
// (they make the keyframes covisible), far static points 20-30 m away beyond the depth range,
// and movers without depth. A mover slides along the epipolar lines between the last two
// keyframes (so that pair alone takes it for a static point at a wrong depth) and moved across
// them before.
struct World {
  PinholeCamera cam;
  Map map;
  std::vector<KeyframeId> kfs;
  std::vector<Vec3> far;  // truth, indexed like the far features
  int anchors = 0;
};

constexpr int kAnchors = 40, kFar = 60, kMovers = 10;

World make_world(double baseline) {
  World w;
  w.cam.fx = w.cam.fy = 500.0;
  w.cam.cx = 320.0;
  w.cam.cy = 240.0;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> ux(-0.5, 0.5), uy(-0.35, 0.35), uz(20.0, 30.0);
  std::vector<OrbDescriptor> desc(kAnchors + kFar + kMovers);
  for (auto& d : desc) d.words = {rng(), rng(), rng(), rng()};
  std::vector<Vec3> anchors;
  for (int i = 0; i < kAnchors; ++i) anchors.emplace_back(ux(rng) * 3.0, uy(rng) * 3.0, 3.0);
  for (int i = 0; i < kFar; ++i) {
    const double z = uz(rng);
    w.far.emplace_back(ux(rng) * z, uy(rng) * z, z);
  }
  std::vector<Vec3> movers;
  for (int i = 0; i < kMovers; ++i) movers.emplace_back(ux(rng) * 20.0, uy(rng) * 20.0, 25.0);
  for (int k = 0; k < 3; ++k) {
    const SE3 T_w_c(SO3(), Vec3(baseline * k, 0, 0));
    FrameFeatures f;
    f.width = 640;
    f.height = 480;
    auto add = [&](const Vec3& p_w, int id, bool with_depth) {
      const Vec3 pc = T_w_c.inverse() * p_w;
      tracking::Keypoint kp;
      kp.px = kp.un =
          Vec2(w.cam.fx * pc.x() / pc.z() + w.cam.cx, w.cam.fy * pc.y() / pc.z() + w.cam.cy);
      f.keypoints.push_back(kp);
      f.descriptors.push_back(desc[static_cast<std::size_t>(id)]);
      f.depth.push_back(with_depth ? pc.z() : 0.0);
      f.sensor_depth.push_back(f.depth.back());
      f.points_c.push_back(with_depth ? pc : Vec3::Zero());
      f.status.push_back(tracking::FeatureStatus::kStatic);
    };
    for (int i = 0; i < kAnchors; ++i) add(anchors[i], i, true);
    for (int i = 0; i < kFar; ++i) add(w.far[i], kAnchors + i, false);
    for (int i = 0; i < kMovers; ++i) {
      // k0: 0.6 m higher; k1 -> k2: 0.3 m along -x (along the epipolar lines).
      const Vec3 at = movers[i] + (k == 0 ? Vec3(0, 0.6, 0) : Vec3(k == 2 ? -0.3 : 0.0, 0, 0));
      add(at, kAnchors + kFar + i, false);
    }
    w.kfs.push_back(w.map.add_keyframe(k, T_w_c, std::move(f)));
  }
  // Anchors are map points from keyframe 0's depth, seen by all three.
  for (int i = 0; i < kAnchors; ++i) {
    const PointId p = w.map.add_point(anchors[i], w.kfs[0], i);
    w.map.add_observation(p, w.kfs[1], i);
    w.map.add_observation(p, w.kfs[2], i);
    w.map.update_point(p);
  }
  for (KeyframeId k : w.kfs) w.map.update_connections(k, 10);
  return w;
}

TEST(Triangulation, FarPointsWithoutDepthBecomeMapPointsWhereTheyAre) {
  World w = make_world(0.5);
  const int created = triangulate_new_points(w.map, w.kfs[2], w.cam);
  EXPECT_GE(created, kFar * 8 / 10);
  const Keyframe* k2 = w.map.keyframe(w.kfs[2]);
  int checked = 0;
  for (int i = 0; i < kFar; ++i) {
    const MapPoint* p = w.map.point(k2->point_of_feature[static_cast<std::size_t>(kAnchors + i)]);
    if (!p) continue;
    ++checked;
    // Noise-free pixels: only the triangulation's conditioning limits the error.
    EXPECT_LT((p->p_w - w.far[static_cast<std::size_t>(i)]).norm(), 0.01 * w.far[i].z()) << i;
    EXPECT_EQ(p->observations.size(), 3u);  // the pair and the confirming keyframe
  }
  EXPECT_EQ(checked, created);
  for (int i = 0; i < kMovers; ++i) {
    EXPECT_EQ(k2->point_of_feature[static_cast<std::size_t>(kAnchors + kFar + i)], kNoPoint) << i;
  }
  // Features with depth are left to Map::create_points_from_depth: anchors keep their points.
  EXPECT_EQ(w.map.num_points(), static_cast<std::size_t>(kAnchors + created));
}

TEST(Triangulation, TwoViewsAloneTakeAMoverAlongTheEpipolarLineForAPoint) {
  World w = make_world(0.5);
  TriangulationOptions two;
  two.min_views = 2;
  triangulate_new_points(w.map, w.kfs[2], w.cam, two);
  const Keyframe* k2 = w.map.keyframe(w.kfs[2]);
  int movers_made = 0;
  for (int i = 0; i < kMovers; ++i) {
    movers_made += k2->point_of_feature[static_cast<std::size_t>(kAnchors + kFar + i)] != kNoPoint;
  }
  EXPECT_GT(movers_made, kMovers / 2);  // why the third view is asked for by default
}

// With a range sensor's depth (FrameFeatures::on_depth_step set), features on an object's
// outline are not triangulated, and a point nearer than the readings reach is refused.
void mark_range_sensor(World& w, bool far_on_outline) {
  for (KeyframeId k : w.kfs) {
    auto& f = w.map.keyframe(k)->features;
    f.on_depth_step.assign(f.size(), 0);
    if (far_on_outline) {
      for (int i = 0; i < kFar; ++i) f.on_depth_step[static_cast<std::size_t>(kAnchors + i)] = 1;
    }
  }
}

TEST(Triangulation, FarPointsBeyondTheReadingsAreKept) {
  World w = make_world(0.5);
  mark_range_sensor(w, false);  // readings reach 3 m (the anchors); the far points lie beyond
  EXPECT_GE(triangulate_new_points(w.map, w.kfs[2], w.cam), kFar * 8 / 10);
}

TEST(Triangulation, OutlineFeaturesAreNotTriangulated) {
  World w = make_world(0.5);
  mark_range_sensor(w, true);
  EXPECT_EQ(triangulate_new_points(w.map, w.kfs[2], w.cam), 0);
  TriangulationOptions all;
  all.skip_depth_steps = false;
  EXPECT_GE(triangulate_new_points(w.map, w.kfs[2], w.cam, all), kFar * 8 / 10);
}

TEST(Triangulation, PointsNearerThanTheSensorsReadingsAreRefused) {
  World w = make_world(0.5);
  mark_range_sensor(w, false);
  // Readings now reach 35 m: a sensor that saw nothing at 20-30 m says nothing is there.
  for (KeyframeId k : w.kfs) {
    auto& f = w.map.keyframe(k)->features;
    for (int i = 0; i < kAnchors; ++i) f.depth[static_cast<std::size_t>(i)] = 35.0;
  }
  EXPECT_EQ(triangulate_new_points(w.map, w.kfs[2], w.cam), 0);
  TriangulationOptions unchecked;
  unchecked.min_depth_past_readings = 0.0;
  EXPECT_GE(triangulate_new_points(w.map, w.kfs[2], w.cam, unchecked), kFar * 8 / 10);
  // Depth that is not a range sensor's (stereo: on_depth_step empty) says nothing of what lies
  // where it has none.
  World stereo = make_world(0.5);
  for (KeyframeId k : stereo.kfs) {
    auto& f = stereo.map.keyframe(k)->features;
    for (int i = 0; i < kAnchors; ++i) f.depth[static_cast<std::size_t>(i)] = 35.0;
  }
  EXPECT_GE(triangulate_new_points(stereo.map, stereo.kfs[2], stereo.cam), kFar * 8 / 10);
}

TEST(Triangulation, NoParallaxNoPoints) {
  World w = make_world(0.01);  // 1 cm baselines, points 20-30 m away: far below a degree
  EXPECT_EQ(triangulate_new_points(w.map, w.kfs[2], w.cam), 0);
  EXPECT_EQ(triangulate_new_points(w.map, 12345, w.cam), 0);  // no such keyframe
}

TEST(Triangulation, SolvedApartFromTheMapItFindsTheSamePoints) {
  World inline_world = make_world(0.5);
  World apart = make_world(0.5);
  const int created =
      triangulate_new_points(inline_world.map, inline_world.kfs[2], inline_world.cam);
  const auto pb = gather_triangulation(apart.map, apart.kfs[2]);
  ASSERT_TRUE(pb.has_value());
  EXPECT_EQ(pb->current.id, apart.kfs[2]);
  EXPECT_EQ(pb->neighbours.size(), 2u);
  const std::vector<NewMapPoint> found = solve_triangulation(*pb, apart.cam);
  EXPECT_EQ(apart.map.num_points(), static_cast<std::size_t>(kAnchors));  // solve wrote nothing
  EXPECT_EQ(static_cast<int>(found.size()), created);
  EXPECT_EQ(apply_triangulation(apart.map, found), created);
  const Keyframe* a = inline_world.map.keyframe(inline_world.kfs[2]);
  const Keyframe* b = apart.map.keyframe(apart.kfs[2]);
  for (std::size_t i = 0; i < a->point_of_feature.size(); ++i) {
    const MapPoint* pa = inline_world.map.point(a->point_of_feature[i]);
    const MapPoint* pb_ = apart.map.point(b->point_of_feature[i]);
    ASSERT_EQ(pa == nullptr, pb_ == nullptr) << i;
    if (pa) {
      EXPECT_EQ(pa->p_w, pb_->p_w) << i;
      EXPECT_EQ(pa->observations.size(), pb_->observations.size()) << i;
    }
  }
  EXPECT_EQ(gather_triangulation(apart.map, 12345), std::nullopt);  // no such keyframe
}

TEST(Triangulation, PointsAppliedAfterTheMapChangedSkipWhatIsGone) {
  World w = make_world(0.5);
  const auto pb = gather_triangulation(w.map, w.kfs[2]);
  ASSERT_TRUE(pb.has_value());
  const std::vector<NewMapPoint> found = solve_triangulation(*pb, w.cam);
  ASSERT_GE(found.size(), static_cast<std::size_t>(kFar * 8 / 10));
  // Meanwhile the tracking thread matched the first point's feature in the new keyframe to
  // another point, and the keyframe paired with the second point was culled.
  const auto [kf0, feature0] = found[0].views[0];
  w.map.add_point(Vec3(0, 0, 5), kf0, feature0);
  const KeyframeId gone = found[1].views[1].first;
  int expected = 0;
  for (std::size_t k = 1; k < found.size(); ++k) expected += found[k].views[1].first != gone;
  w.map.erase_keyframe(gone);
  const std::size_t before = w.map.num_points();
  const int created = apply_triangulation(w.map, found);
  EXPECT_GT(expected, 0);
  EXPECT_EQ(created, expected);
  EXPECT_EQ(w.map.num_points(), before + static_cast<std::size_t>(created));
  for (const auto& [id, p] : w.map.points()) {
    for (const auto& [kf, feature] : p.observations) {
      (void)feature;
      EXPECT_NE(kf, gone);  // no observation of the culled keyframe
    }
  }
}

}  // namespace
}  // namespace kestrel::mapping
