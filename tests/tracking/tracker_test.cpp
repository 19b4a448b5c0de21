#include "tracking/tracker.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <memory>
#include <random>

#include "io/image_io.hpp"
#include "synthetic_scene.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::tracking {
namespace {

PinholeCamera synthetic_camera() {
  PinholeCamera c;
  c.fx = c.fy = 525.0;
  c.cx = 319.5;
  c.cy = 239.5;
  return c;
}

PinholeCamera tum_camera() {
  PinholeCamera c;
  c.fx = 535.4;
  c.fy = 539.2;
  c.cx = 320.1;
  c.cy = 247.6;
  return c;
}

// A black frame with no depth: nothing to track.
RgbdFrame blank_frame(const PinholeCamera& cam) {
  RgbdFrame blank;
  blank.color = Image::allocate(cam.width, cam.height, 1, PixelType::kU8);
  blank.depth = Image::allocate(cam.width, cam.height, 1, PixelType::kU16);
  return blank;
}

// Tracks the first n frames of the office along path: the map the tests then lose, find again
// or leave.
::testing::AssertionResult tracks_office(Tracker& tracker, const PinholeCamera& cam,
                                         const test::SyntheticScene& scene,
                                         const std::vector<SE3>& path, int n = 20) {
  for (int i = 0; i < n; ++i) {
    const TrackingState s =
        tracker.track(scene.render(cam, path[static_cast<std::size_t>(i)])).state;
    if (s != TrackingState::kOk) {
      return ::testing::AssertionFailure() << "frame " << i << " " << to_string(s);
    }
  }
  return ::testing::AssertionSuccess();
}

// The IMU's prediction of a frame's pose, with its sigmas (radians, metres).
MotionPrior imu_prior(const SE3& T_w_c, double rotation_sigma, double translation_sigma) {
  MotionPrior p;
  p.T_w_c = T_w_c;
  p.rotation_sigma = rotation_sigma;
  p.translation_sigma = translation_sigma;
  return p;
}

// Moves every feature right of column x by dx pixels: a consensus of movers crossing the view.
void shift_right_of(FrameFeatures& f, double x, double dx) {
  for (Keypoint& k : f.keypoints) {
    if (k.un.x() > x) {
      k.px.x() += dx;
      k.un.x() += dx;
    }
  }
}

RgbdFrame tum_frame() {
  RgbdFrame f;
  f.color = io::load_image(test::shared_data("tum_fr3/frame/rgb_1341846313.592026.png").string(),
                           io::ImageKind::kColor);
  f.depth = io::load_image(test::shared_data("tum_fr3/frame/depth_1341846313.592088.png").string(),
                           io::ImageKind::kDepth);
  return f;
}

TEST(Tracker, SyntheticSequenceWithinOneCentimetreAndNeverLost) {
  const PinholeCamera cam = synthetic_camera();
  const test::SyntheticScene scene = test::SyntheticScene::office();
  const std::vector<SE3> path = test::smooth_path(60);
  Tracker tracker(cam);
  tracker.set_initial_pose(path[0]);
  double sum2 = 0.0, worst = 0.0, worst_deg = 0.0;
  int keyframes = 0;
  for (std::size_t i = 0; i < path.size(); ++i) {
    const RgbdFrame frame = scene.render(cam, path[i], static_cast<Timestamp>(i) * 33'333'333);
    const TrackResult r = tracker.track(frame);
    ASSERT_TRUE(r.state == TrackingState::kOk) << "frame " << i << " " << to_string(r.state);
    ASSERT_TRUE(r.T_w_c.is_finite());
    const double e = (r.T_w_c.translation() - path[i].translation()).norm();
    sum2 += e * e;
    worst = std::max(worst, e);
    worst_deg = std::max(worst_deg, (r.T_w_c.so3().inverse() * path[i].so3()).angle() * 180 / M_PI);
    keyframes += r.new_keyframe ? 1 : 0;
    if (i > 0) {
      EXPECT_GT(r.inliers, 100) << "frame " << i;
    }
  }
  const double rmse = std::sqrt(sum2 / static_cast<double>(path.size()));
  std::cerr << "synthetic: RMSE " << rmse * 1000 << " mm, worst " << worst * 1000 << " mm, "
            << worst_deg << " deg, " << keyframes << " keyframes, " << tracker.map().num_points()
            << " points\n";
  EXPECT_LT(rmse, 0.01);
  EXPECT_GT(keyframes, 1);
}

TEST(Tracker, RealFrameAgainstItselfIsIdentity) {
  Tracker tracker(tum_camera());
  const RgbdFrame frame = tum_frame();
  const TrackResult first = tracker.track(frame);
  ASSERT_EQ(first.state, TrackingState::kOk);
  ASSERT_TRUE(first.new_keyframe);
  const TrackResult second = tracker.track(frame);
  ASSERT_EQ(second.state, TrackingState::kOk);
  EXPECT_GT(second.inliers, 300);
  EXPECT_LT(second.T_w_c.translation().norm(), 1e-6);
  EXPECT_LT(second.T_w_c.so3().angle(), 1e-6);
  EXPECT_FALSE(second.new_keyframe);
}

TEST(Tracker, RealFrameWithAWrongPredictionStillFindsIdentity) {
  Tracker tracker(tum_camera());
  const RgbdFrame frame = tum_frame();
  tracker.track(frame);
  // 20 cm and 6 degrees off: too far for the projection search, so PnP has to step in.
  const SE3 wrong(SO3::exp(Vec3(0.0, 0.1, 0.0)), Vec3(0.2, 0.0, 0.0));
  const TrackResult r = tracker.track(frame, wrong);
  ASSERT_EQ(r.state, TrackingState::kOk);
  EXPECT_LT(r.T_w_c.translation().norm(), 1e-4);
  EXPECT_LT(r.T_w_c.so3().angle(), 1e-4);
}

TEST(Tracker, KeepMaskExcludesFeaturesAndAllDynamicIsLost) {
  Tracker tracker(tum_camera());
  const RgbdFrame frame = tum_frame();
  tracker.track(frame);
  FrameFeatures f = tracker.extractor().extract(frame);
  const std::vector<std::uint8_t> none(f.size(), 0);
  const TrackResult r = tracker.track(f, std::nullopt, &none);
  EXPECT_EQ(r.state, TrackingState::kLost);
  EXPECT_EQ(r.inliers, 0);
  EXPECT_TRUE(r.T_w_c.is_finite());
  EXPECT_LT(r.T_w_c.translation().norm(), 1e-12);  // the last good pose
  const std::vector<std::uint8_t> wrong_size(3, 1);
  EXPECT_THROW(tracker.track(f, std::nullopt, &wrong_size), std::invalid_argument);
}

// The gyro's rotation prior weighs in the next track() only: tight, it holds the rotation where
// the gyro says (the points still place the translation); the frame after is vision's again.
TEST(Tracker, RotationPriorHoldsOneFrameThenClears) {
  Tracker tracker(tum_camera());
  const RgbdFrame frame = tum_frame();
  tracker.track(frame);
  const SO3 turned = SO3::exp(Vec3(0.0, 0.002, 0.0));
  tracker.set_rotation_prior(turned, 1e-6);
  const TrackResult held = tracker.track(frame);
  ASSERT_EQ(held.state, TrackingState::kOk);
  EXPECT_LT((held.T_w_c.so3().inverse() * turned).angle(), 1e-4);
  EXPECT_TRUE(held.T_w_c.is_finite());
  const TrackResult next = tracker.track(frame);
  ASSERT_EQ(next.state, TrackingState::kOk);
  EXPECT_LT(next.T_w_c.so3().angle(), 1e-6);
  // A loose prior leaves vision alone; a broken one is none.
  tracker.set_rotation_prior(turned, 1.0);
  EXPECT_LT(tracker.track(frame).T_w_c.so3().angle(), 1e-5);
  tracker.set_rotation_prior(turned, std::nan(""));
  EXPECT_LT(tracker.track(frame).T_w_c.so3().angle(), 1e-6);
}

TEST(Tracker, NonFinitePredictionIsIgnored) {
  Tracker tracker(tum_camera());
  const RgbdFrame frame = tum_frame();
  tracker.track(frame);
  SE3 bad;
  bad.translation() = Vec3(std::nan(""), 0, 0);
  const TrackResult r = tracker.track(frame, bad);
  EXPECT_EQ(r.state, TrackingState::kOk);
  EXPECT_TRUE(r.T_w_c.is_finite());
  EXPECT_LT(r.T_w_c.translation().norm(), 1e-6);
}

TEST(Tracker, WaitsForDepthThenLosesOnBlankAndRelocalizes) {
  const PinholeCamera cam = synthetic_camera();
  const test::SyntheticScene scene = test::SyntheticScene::office();
  const std::vector<SE3> path = test::smooth_path(60);
  Tracker tracker(cam);
  const RgbdFrame blank = blank_frame(cam);
  EXPECT_EQ(tracker.track(blank).state, TrackingState::kInitializing);
  ASSERT_TRUE(tracks_office(tracker, cam, scene, path));
  const SE3 last = tracker.last_pose();
  const TrackResult lost = tracker.track(blank);
  EXPECT_EQ(lost.state, TrackingState::kLost);
  EXPECT_LT((lost.T_w_c.translation() - last.translation()).norm(), 1e-12);
  // Jump ahead on the path: no motion prior is valid, relocalization must find the pose.
  const TrackResult back = tracker.track(scene.render(cam, path[30]));
  ASSERT_EQ(back.state, TrackingState::kRelocalized);
  EXPECT_LT((back.T_w_c.translation() - path[30].translation()).norm(), 0.01);
  const TrackResult next = tracker.track(scene.render(cam, path[31]));
  EXPECT_EQ(next.state, TrackingState::kOk);
  EXPECT_LT((next.T_w_c.translation() - path[31].translation()).norm(), 0.01);
}

// A live System falling behind marks frames busy: a lost track then searches the whole map only
// on every busy_relocalize_every-th lost frame (the first one included), and as soon as it is
// not busy again.
TEST(Tracker, BusyLostTrackSearchesTheWholeMapOnlyEveryNthFrame) {
  const PinholeCamera cam = synthetic_camera();
  const test::SyntheticScene scene = test::SyntheticScene::office();
  const std::vector<SE3> path = test::smooth_path(60);
  TrackerOptions o;
  o.busy_relocalize_every = 3;
  o.coast_frames = 0;  // no guess from the last motion: only the whole-map search can find it
  Tracker tracker(cam, o);
  const RgbdFrame blank = blank_frame(cam);
  ASSERT_TRUE(tracks_office(tracker, cam, scene, path));
  ASSERT_EQ(tracker.track(blank).state, TrackingState::kLost);  // lost here
  tracker.set_busy(true);
  const TrackResult first = tracker.track(blank);  // lost frame 0: searches
  EXPECT_FALSE(first.global_search_skipped);
  tracker.set_busy(true);
  const TrackResult second = tracker.track(scene.render(cam, path[30]));  // lost frame 1: not
  EXPECT_TRUE(second.global_search_skipped);
  EXPECT_EQ(second.state, TrackingState::kLost);
  EXPECT_TRUE(second.T_w_c.is_finite());
  // Not busy: the same view relocalizes at once.
  const TrackResult back = tracker.track(scene.render(cam, path[30]));
  EXPECT_FALSE(back.global_search_skipped);
  ASSERT_EQ(back.state, TrackingState::kRelocalized);
  EXPECT_LT((back.T_w_c.translation() - path[30].translation()).norm(), 0.01);
}

// Long lost, with the IMU's attitude but no position: a relocalization that faces another way
// than the gyro says is a look-alike place and is refused; one that agrees is taken.
TEST(Tracker, RelocalizationMustAgreeWithTheAttitudeHint) {
  const PinholeCamera cam = synthetic_camera();
  const test::SyntheticScene scene = test::SyntheticScene::office();
  const std::vector<SE3> path = test::smooth_path(60);
  const RgbdFrame blank = blank_frame(cam);
  for (const bool agree : {false, true}) {
    Tracker tracker(cam);
    ASSERT_TRUE(tracks_office(tracker, cam, scene, path));
    ASSERT_EQ(tracker.track(blank).state, TrackingState::kLost);
    const SO3 truth = path[30].so3();
    // Turned 40 degrees about the camera's vertical axis: outside the 20-degree tolerance.
    const SO3 hint = agree ? truth : truth * SO3::exp(Vec3(0.0, 0.7, 0.0));
    tracker.set_attitude_hint(hint);
    const TrackResult r = tracker.track(scene.render(cam, path[30]));
    if (agree) {
      EXPECT_EQ(r.state, TrackingState::kRelocalized);
      EXPECT_FALSE(r.relocalization_rejected);
      EXPECT_LT((r.T_w_c.translation() - path[30].translation()).norm(), 0.01);
    } else {
      EXPECT_EQ(r.state, TrackingState::kLost);
      EXPECT_TRUE(r.relocalization_rejected);
      EXPECT_TRUE(r.T_w_c.is_finite());
    }
  }
}

// Lost with a prediction, the track bridges to a new local map at it after
// bridge_after_lost_frames, unless the frame before was tracked frame to frame
// (set_hold_bridge): then it keeps looking for its map; once no longer held, it bridges.
TEST(Tracker, AHeldBridgeWaitsForTheMap) {
  const PinholeCamera cam = synthetic_camera();
  const test::SyntheticScene scene = test::SyntheticScene::office();
  const std::vector<SE3> path = test::smooth_path(60);
  TrackerOptions opt;
  opt.bridge_after_lost_frames = 3;
  Tracker tracker(cam, opt);
  ASSERT_TRUE(tracks_office(tracker, cam, scene, path));
  const SE3 last = tracker.last_pose();
  const RgbdFrame elsewhere = tum_frame();
  for (int i = 0; i < 3 * opt.bridge_after_lost_frames; ++i) {
    tracker.set_hold_bridge(true);
    const TrackResult r = tracker.track(elsewhere, std::optional<SE3>(last));
    ASSERT_EQ(r.state, TrackingState::kLost) << "frame " << i;
    EXPECT_FALSE(r.bridged);
  }
  const TrackResult r = tracker.track(elsewhere, std::optional<SE3>(last));
  EXPECT_EQ(r.state, TrackingState::kOk);
  EXPECT_TRUE(r.bridged);
  EXPECT_LT((r.T_w_c.translation() - last.translation()).norm(), 1e-9);
}

// A pose 5 cm from the IMU's prediction (chi-square 100 in its sigmas) passes the options' gate
// of 150; with the gate set to 16.8 for one track() it is re-matched around the prediction,
// still disagrees, and the frame is dropped. The next track() has the options' gate again.
// (At 3 cm, since each frame's depth joined its pose, the matches found around the prediction
// settle on a pose between the two, 1.7 cm from the truth, within the gate.)
TEST(Tracker, APriorGateForOneFrame) {
  const PinholeCamera cam = synthetic_camera();
  const test::SyntheticScene scene = test::SyntheticScene::office();
  const std::vector<SE3> path = test::smooth_path(60);
  TrackerOptions opt;
  opt.prior_gate_chi2 = 150.0;
  opt.prior_in_optimization = false;
  Tracker tracker(cam, opt);
  ASSERT_TRUE(tracks_office(tracker, cam, scene, path));
  auto prior_at = [&](std::size_t i) {
    MotionPrior p;
    p.T_w_c = SE3(path[i].so3(), path[i].translation() + Vec3(0.05, 0.0, 0.0));
    p.rotation_sigma = 0.001;
    p.translation_sigma = 0.005;
    return p;
  };
  const TrackResult wide =
      tracker.track(tracker.extractor().extract(scene.render(cam, path[20])), prior_at(20));
  ASSERT_EQ(wide.state, TrackingState::kOk);
  EXPECT_FALSE(wide.prior_conflict);
  EXPECT_GT(wide.prior_chi2, 16.8);
  tracker.set_prior_gate_chi2(16.8);
  const TrackResult tight =
      tracker.track(tracker.extractor().extract(scene.render(cam, path[21])), prior_at(21));
  EXPECT_TRUE(tight.prior_conflict);
  EXPECT_EQ(tight.state, TrackingState::kLost);
  const TrackResult again =
      tracker.track(tracker.extractor().extract(scene.render(cam, path[22])), prior_at(22));
  EXPECT_NE(again.state, TrackingState::kLost);
  EXPECT_FALSE(again.prior_conflict);
}

// Movers the filter let through (cars driving along a drone's path) pull vision off the IMU's
// prediction with a consensus of their own: here a sparse view (every 8th feature with depth)
// whose right half is shifted together by 1.2 px. Re-matched around the prediction and optimized
// alone, the points still pull the pose off, and the frame is lost; with the prediction as a
// factor (prior_in_conflict) the pose is held near it, still explaining the same points, and the
// frame is tracked. A prediction that explains far fewer points than vision's own pose is still
// refused (APriorGateForOneFrame).
TEST(Tracker, APriorInTheConflictHoldsAWeaklySeenPose) {
  const PinholeCamera cam = synthetic_camera();
  const test::SyntheticScene scene = test::SyntheticScene::office();
  const std::vector<SE3> path = test::smooth_path(60);
  TrackerOptions gate_only;
  gate_only.prior_in_optimization = false;
  gate_only.prior_in_conflict = false;
  gate_only.inline_mapping = false;  // the pose as tracked, before a local BA of the shifted view
  TrackerOptions held = gate_only;
  held.prior_in_conflict = true;
  Tracker a(cam, gate_only), b(cam, held);
  ASSERT_TRUE(tracks_office(a, cam, scene, path));
  ASSERT_TRUE(tracks_office(b, cam, scene, path));
  FrameFeatures f = a.extractor().extract(scene.render(cam, path[20]));
  std::vector<std::uint8_t> keep(f.size(), 0);
  int kept = 0;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (f.depth[i] > 0 && i % 8 == 0) keep[i] = 1, ++kept;
  }
  shift_right_of(f, cam.cx, 1.2);
  const MotionPrior imu = imu_prior(path[20], 0.0003, 0.001);
  const TrackResult alone = a.track(f, imu, &keep);
  EXPECT_TRUE(alone.prior_conflict);
  EXPECT_EQ(alone.state, TrackingState::kLost) << kept << " kept";
  const TrackResult r = b.track(f, imu, &keep);
  EXPECT_TRUE(r.prior_conflict);
  ASSERT_EQ(r.state, TrackingState::kOk) << kept << " kept";
  EXPECT_LE(r.prior_chi2, held.prior_gate_chi2);
  EXPECT_LT((r.T_w_c.translation() - path[20].translation()).norm(), 0.003);
  EXPECT_LT((r.T_w_c.so3().inverse() * path[20].so3()).angle(), 0.001);
}

// A prediction 3 cm off against the whole, well-seen office: held there by the prior, the pose
// fits well under half the points vision's own pose fits, so vision is the one to believe and the
// frame is refused; without the share rule the prior's pose would have been taken.
TEST(Tracker, AHeldPoseMustExplainWhatVisionExplains) {
  const PinholeCamera cam = synthetic_camera();
  const test::SyntheticScene scene = test::SyntheticScene::office();
  const std::vector<SE3> path = test::smooth_path(60);
  TrackerOptions opt;
  opt.prior_in_optimization = false;
  opt.inline_mapping = false;
  ASSERT_TRUE(opt.prior_in_conflict);
  TrackerOptions any_share = opt;
  any_share.prior_conflict_min_share = 0.0;
  Tracker strict(cam, opt), lax(cam, any_share);
  ASSERT_TRUE(tracks_office(strict, cam, scene, path));
  ASSERT_TRUE(tracks_office(lax, cam, scene, path));
  const FrameFeatures f = strict.extractor().extract(scene.render(cam, path[20]));
  const MotionPrior off =
      imu_prior(SE3(path[20].so3(), path[20].translation() + Vec3(0.03, 0.0, 0.0)), 0.001, 0.005);
  const TrackResult refused = strict.track(f, off);
  EXPECT_TRUE(refused.prior_conflict);
  EXPECT_EQ(refused.state, TrackingState::kLost);
  const TrackResult taken = lax.track(f, off);
  EXPECT_TRUE(taken.prior_conflict);
  ASSERT_EQ(taken.state, TrackingState::kOk);
  EXPECT_GT((taken.T_w_c.translation() - path[20].translation()).norm(), 0.01);
}

// Most of the view shifted together by 9 px (a crowd walking across it): vision follows the
// crowd, away from the prediction. Around the prediction the search finds mostly the rest; held
// there they are too few against vision's inliers, but alone they agree with the prediction, and
// the frame is tracked exactly as it was before the prior held anything (prior_in_conflict off).
TEST(Tracker, PointsThatAgreeWithThePredictionAloneStillDecide) {
  const PinholeCamera cam = synthetic_camera();
  const test::SyntheticScene scene = test::SyntheticScene::office();
  const std::vector<SE3> path = test::smooth_path(60);
  TrackerOptions opt;
  opt.prior_in_optimization = false;
  opt.prior_gate_chi2 = 150.0;
  opt.inline_mapping = false;
  TrackerOptions never_held = opt;
  never_held.prior_in_conflict = false;
  Tracker tracker(cam, opt), before(cam, never_held);
  ASSERT_TRUE(tracks_office(tracker, cam, scene, path));
  ASSERT_TRUE(tracks_office(before, cam, scene, path));
  FrameFeatures f = tracker.extractor().extract(scene.render(cam, path[20]));
  std::vector<double> xs;
  for (const auto& k : f.keypoints) xs.push_back(k.un.x());
  std::nth_element(xs.begin(), xs.begin() + xs.size() * 2 / 5, xs.end());
  shift_right_of(f, xs[xs.size() * 2 / 5], 9.0);  // the right 60% move
  const MotionPrior imu = imu_prior(path[20], 0.001, 0.002);
  const TrackResult r = tracker.track(f, imu);
  const TrackResult b = before.track(f, imu);
  EXPECT_TRUE(r.prior_conflict);
  ASSERT_EQ(r.state, TrackingState::kOk);
  ASSERT_EQ(b.state, TrackingState::kOk);
  EXPECT_EQ(r.inliers, b.inliers);
  EXPECT_LT((r.T_w_c.translation() - b.T_w_c.translation()).norm(), 1e-9);
  EXPECT_LT((r.T_w_c.translation() - path[20].translation()).norm(), 0.01);
}

// A frame left with fewer points than min_inliers (a walker filling the near view) is still
// tracked when those points agree with the IMU's prediction (ORB-SLAM3's 15 in its inertial
// modes); the same points without the prediction are not enough.
TEST(Tracker, FewInliersThatAgreeWithTheImuAreEnough) {
  const PinholeCamera cam = synthetic_camera();
  const test::SyntheticScene scene = test::SyntheticScene::office();
  const std::vector<SE3> path = test::smooth_path(60);
  Tracker with_imu(cam), vision_alone(cam);
  ASSERT_TRUE(tracks_office(with_imu, cam, scene, path));
  ASSERT_TRUE(tracks_office(vision_alone, cam, scene, path));
  const FrameFeatures f = with_imu.extractor().extract(scene.render(cam, path[20]));
  // Every 40th feature with depth: 25 points spread over the view, 18 of them inliers.
  std::vector<std::uint8_t> keep(f.size(), 0);
  int kept = 0;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (f.depth[i] > 0 && i % 40 == 0) keep[i] = 1, ++kept;
  }
  const MotionPrior imu = imu_prior(path[20], 0.002, 0.01);
  const TrackResult r = with_imu.track(f, imu, &keep);
  ASSERT_EQ(r.state, TrackingState::kOk) << kept << " kept";
  EXPECT_GE(r.inliers, 15);
  EXPECT_LT(r.inliers, TrackerOptions{}.min_inliers);
  EXPECT_LT((r.T_w_c.translation() - path[20].translation()).norm(), 0.02);
  EXPECT_EQ(vision_alone.track(f, std::optional<SE3>(path[20]), &keep).state, TrackingState::kLost);
}

// Lost without any prediction, somewhere the map never saw (a real room after the synthetic
// office): relocalization cannot succeed, so after restart_after_lost_frames the track restarts
// at the last position, turned to the attitude hint, and goes on from there.
TEST(Tracker, LongLostWithoutPredictionRestartsAtTheLastPose) {
  const PinholeCamera cam = synthetic_camera();
  const test::SyntheticScene scene = test::SyntheticScene::office();
  const std::vector<SE3> path = test::smooth_path(60);
  TrackerOptions opt;
  opt.restart_after_lost_frames = 8;
  opt.coast_frames = 3;
  Tracker tracker(cam, opt);
  ASSERT_TRUE(tracks_office(tracker, cam, scene, path));
  const SE3 last = tracker.last_pose();
  const SO3 hint = last.so3() * SO3::exp(Vec3(0.0, 0.3, 0.0));
  tracker.set_attitude_hint(hint);
  const RgbdFrame elsewhere = tum_frame();
  for (int i = 0; i < opt.restart_after_lost_frames; ++i) {
    const TrackResult r = tracker.track(elsewhere);
    ASSERT_EQ(r.state, TrackingState::kLost) << "frame " << i;
    EXPECT_FALSE(r.restarted);
  }
  const TrackResult r = tracker.track(elsewhere);
  ASSERT_EQ(r.state, TrackingState::kOk);
  EXPECT_TRUE(r.restarted);
  EXPECT_TRUE(r.bridged);
  EXPECT_TRUE(r.new_keyframe);
  EXPECT_LT((r.T_w_c.translation() - last.translation()).norm(), 1e-9);
  EXPECT_LT((r.T_w_c.so3() * hint.inverse()).log().norm(), 1e-9);
  const TrackResult next = tracker.track(elsewhere);
  EXPECT_EQ(next.state, TrackingState::kOk);
  EXPECT_FALSE(next.restarted);
  EXPECT_LT((next.T_w_c.translation() - last.translation()).norm(), 0.01);

  // Never restarts when told not to.
  opt.restart_after_lost_frames = 0;
  Tracker never(cam, opt);
  for (int i = 0; i < 20; ++i) never.track(scene.render(cam, path[static_cast<std::size_t>(i)]));
  for (int i = 0; i < 20; ++i) EXPECT_EQ(never.track(elsewhere).state, TrackingState::kLost);
}

// Hand-made features of a still camera: `near` features at 2 m on the left half (feature i at a
// place and with a descriptor of its own), then `far` ones at 8 m on the right half.
FrameFeatures still_features(const PinholeCamera& cam, int near, int far, int first_near = 0) {
  FrameFeatures f;
  f.width = cam.width;
  f.height = cam.height;
  const auto add = [&](int id, double u, double v, double z) {
    Keypoint k;
    k.px = k.un = Vec2(u, v);
    f.keypoints.push_back(k);
    OrbDescriptor d;
    // Far apart in Hamming distance: every feature its own pattern of 64-bit words.
    std::mt19937_64 rng(static_cast<std::uint64_t>(id) + 1);
    for (auto& w : d.words) w = rng();
    f.descriptors.push_back(d);
    f.depth.push_back(z);
    f.points_c.push_back(Vec3((u - cam.cx) / cam.fx * z, (v - cam.cy) / cam.fy * z, z));
    f.status.push_back(FeatureStatus::kStatic);
  };
  for (int i = first_near; i < first_near + near; ++i) {
    add(i, 20.0 + 24.0 * (i % 12), 20.0 + 24.0 * (i / 12), 2.0);
  }
  for (int i = 0; i < far; ++i) {
    add(1000 + i, 340.0 + 24.0 * (i % 12), 20.0 + 24.0 * (i / 12), 8.0);
  }
  f.build_grid();
  return f;
}

// A crowd hides most of what the first keyframe mapped (50 of its 110 points still seen) while
// 65 features of farther scenery come into view: ORB-SLAM's rules keep the keyframe (50 inliers
// are not below 0.4 of 110; 65 unmatched "close" features are not over 70), and the track would
// go on thinning; TrackerOptions::weak_inliers makes a keyframe that maps the far scenery.
TEST(Tracker, WeakTrackingWithUnmappedSceneryMakesAKeyframe) {
  const PinholeCamera cam = synthetic_camera();
  for (const int weak_inliers : {0, 60}) {
    TrackerOptions o;
    o.weak_inliers = weak_inliers;
    o.triangulate = false;
    Tracker tracker(cam, o);
    const TrackResult first = tracker.track(still_features(cam, 110, 0), std::nullopt);
    ASSERT_EQ(first.state, TrackingState::kOk);
    ASSERT_TRUE(first.new_keyframe);
    ASSERT_EQ(tracker.map().num_points(), 110u);
    const TrackResult r = tracker.track(still_features(cam, 50, 65, 60), SE3());
    ASSERT_EQ(r.state, TrackingState::kOk);
    EXPECT_EQ(r.inliers, 50);
    EXPECT_LT(r.T_w_c.translation().norm(), 1e-6);
    EXPECT_EQ(r.new_keyframe, weak_inliers > 0) << "weak_inliers " << weak_inliers;
    EXPECT_EQ(tracker.map().num_points(), weak_inliers > 0 ? 175u : 110u);
  }
}

// Back and forth over the same short path: with culling the map keeps fewer keyframes than
// were inserted, every culled one is gone from it, and it stays consistent and accurate.
TEST(Tracker, KeyframeCullingKeepsARevisitedMapSmallAndConsistent) {
  const PinholeCamera cam = synthetic_camera();
  const test::SyntheticScene scene = test::SyntheticScene::office();
  const std::vector<SE3> leg = test::smooth_path(12);
  std::vector<SE3> path;
  for (int pass = 0; pass < 4; ++pass) {
    for (std::size_t i = 0; i < leg.size(); ++i)
      path.push_back(leg[pass % 2 ? leg.size() - 1 - i : i]);
  }
  struct Outcome {
    std::size_t inserted = 0, culled = 0, in_map = 0;
    double rmse = 0.0;
  };
  const auto run = [&](double redundancy, std::unique_ptr<Tracker>& tracker) {
    TrackerOptions o;
    o.keyframe_cull_redundancy = redundancy;
    // A keyframe every frame (as a crowded scene nearly does), so revisits leave redundant ones.
    o.keyframe_ratio = 2.0;
    tracker = std::make_unique<Tracker>(cam, o);
    tracker->set_initial_pose(path[0]);
    Outcome r;
    double sum2 = 0.0;
    for (std::size_t i = 0; i < path.size(); ++i) {
      const RgbdFrame frame = scene.render(cam, path[i], static_cast<Timestamp>(i) * 33'333'333);
      const TrackResult t = tracker->track(frame);
      EXPECT_EQ(t.state, TrackingState::kOk) << "frame " << i;
      r.inserted += t.new_keyframe ? 1 : 0;
      r.culled += t.culled_keyframes.size();
      for (mapping::KeyframeId id : t.culled_keyframes) {
        EXPECT_EQ(tracker->map().keyframe(id), nullptr);
        EXPECT_NE(id, t.keyframe_id);
      }
      sum2 += (t.T_w_c.translation() - path[i].translation()).squaredNorm();
    }
    r.in_map = tracker->map().num_keyframes();
    r.rmse = std::sqrt(sum2 / static_cast<double>(path.size()));
    return r;
  };
  std::unique_ptr<Tracker> culling, keeping;
  const Outcome c = run(0.9, culling);
  const Outcome k = run(0.0, keeping);
  std::cerr << "culling: " << c.inserted << " keyframes inserted, " << c.culled << " culled, "
            << c.in_map << " kept, RMSE " << c.rmse * 1000 << " mm; without: " << k.in_map
            << " kept, RMSE " << k.rmse * 1000 << " mm\n";
  EXPECT_EQ(k.culled, 0u);
  EXPECT_EQ(k.in_map, k.inserted);
  EXPECT_GT(c.culled, 0u);
  EXPECT_EQ(c.in_map + c.culled, c.inserted);
  EXPECT_LT(c.in_map, k.in_map);
  EXPECT_LT(c.rmse, 0.01);
  // Consistent: every observation links a live keyframe and point both ways.
  const mapping::Map& m = culling->map();
  for (const auto& [pid, p] : m.points()) {
    EXPECT_FALSE(p.observations.empty());
    for (const auto& [kid, feature] : p.observations) {
      const mapping::Keyframe* kf = m.keyframe(kid);
      ASSERT_NE(kf, nullptr) << "point " << pid << " observed by culled keyframe " << kid;
      EXPECT_EQ(kf->point_of_feature[static_cast<std::size_t>(feature)], pid);
    }
  }
  for (const auto& [kid, kf] : m.keyframes()) {
    for (const auto& [other, w] : kf.connections) EXPECT_NE(m.keyframe(other), nullptr);
  }
}

// With the local-mapping thread (inline_mapping off), a keyframe's triangulation is handed out
// and its insertion completes only when the points come back: no new keyframe is decided
// meanwhile, its local BA is requested then, and the track goes on from the depth points.
TEST(Tracker, KeyframeWaitsForItsTriangulationFromTheMappingThread) {
  const PinholeCamera cam = synthetic_camera();
  const test::SyntheticScene scene = test::SyntheticScene::office();
  const std::vector<SE3> path = test::smooth_path(60);
  TrackerOptions o;
  o.inline_mapping = false;
  o.triangulate = true;
  o.keyframe_ratio = 2.0;  // would take a keyframe every frame
  Tracker tracker(cam, o);
  tracker.set_initial_pose(path[0]);
  std::optional<mapping::TriangulationProblem> in_flight;
  int frames_in_flight = 0, keyframes = 0, finished = 0;
  double sum2 = 0.0;
  for (std::size_t i = 0; i < path.size(); ++i) {
    // The mapping thread answers two frames after it was asked.
    if (in_flight && ++frames_in_flight > 2) {
      const mapping::KeyframeId kid = in_flight->current.id;
      EXPECT_TRUE(tracker.keyframe_pending(kid));
      EXPECT_FALSE(tracker.take_local_ba().has_value());  // not before its points
      std::vector<mapping::KeyframeId> culled;
      EXPECT_TRUE(
          tracker.finish_keyframe(kid, mapping::solve_triangulation(*in_flight, cam), culled));
      EXPECT_FALSE(tracker.keyframe_pending(kid));
      const auto ba = tracker.take_local_ba();
      ASSERT_TRUE(ba.has_value());
      EXPECT_EQ(ba->current, kid);
      EXPECT_FALSE(tracker.finish_keyframe(kid, {}, culled));  // once
      in_flight.reset();
      ++finished;
    }
    const RgbdFrame frame = scene.render(cam, path[i], static_cast<Timestamp>(i) * 33'333'333);
    const TrackResult r = tracker.track(frame);
    ASSERT_EQ(r.state, TrackingState::kOk) << "frame " << i;
    if (r.new_keyframe && i > 0) {
      EXPECT_FALSE(in_flight.has_value()) << "frame " << i << ": a keyframe while one pends";
      ++keyframes;
    }
    if (auto pb = tracker.take_triangulation()) {
      EXPECT_EQ(pb->current.id, r.keyframe_id);
      EXPECT_TRUE(tracker.keyframe_pending(r.keyframe_id));
      in_flight = std::move(pb);
      frames_in_flight = 0;
    }
    sum2 += (r.T_w_c.translation() - path[i].translation()).squaredNorm();
  }
  EXPECT_GT(keyframes, 10);
  EXPECT_GE(finished, keyframes - 1);
  EXPECT_LT(std::sqrt(sum2 / static_cast<double>(path.size())), 0.01);
}

}  // namespace
}  // namespace kestrel::tracking
