// The loop gate: a verified loop is kept only when it agrees with the odometry within the drift
// the path between its two keyframes allows.
#include "loop/loop_gate.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace kestrel::loop {
namespace {

constexpr double kDeg = M_PI / 180.0;

// Keyframes every metre along x, looking the same way: ids 0..n-1.
std::map<PoseId, SE3> straight_path(int n) {
  std::map<PoseId, SE3> poses;
  for (int i = 0; i < n; ++i) poses[i] = SE3(SO3(), Vec3(i, 0.0, 0.0));
  return poses;
}

SE3 yaw(double rad, const Vec3& t) { return SE3(SO3::exp(Vec3(0.0, 0.0, rad)), t); }

TEST(LoopGate, PathLengthFollowsTheKeyframesInIdOrder) {
  auto poses = straight_path(5);
  poses[2] = SE3(SO3(), Vec3(2.0, 3.0, 0.0));  // a detour: 1 + sqrt(10) + sqrt(10) + 1
  EXPECT_NEAR(path_length(poses, 0, 4), 2.0 + 2.0 * std::sqrt(10.0), 1e-12);
  EXPECT_NEAR(path_length(poses, 4, 0), path_length(poses, 0, 4), 1e-12);
  EXPECT_NEAR(path_length(poses, 1, 1), 0.0, 1e-12);
  poses.erase(3);  // a culled keyframe: the path goes straight past it
  EXPECT_NEAR(path_length(poses, 2, 4), std::sqrt(4.0 + 9.0), 1e-12);
}

TEST(LoopGate, KeepsALoopThatAgreesWithTheOdometry) {
  const auto poses = straight_path(3);
  // Odometry: the query is 2 m ahead of the match; the loop measures the same.
  const auto r = check_loop_drift(poses, 0, 2, SE3(SO3(), Vec3(2.0, 0.0, 0.0)));
  EXPECT_TRUE(r.plausible);
  EXPECT_NEAR(r.path_m, 2.0, 1e-12);
  EXPECT_NEAR(r.translation_m, 0.0, 1e-12);
  EXPECT_NEAR(r.rotation_rad, 0.0, 1e-12);
}

TEST(LoopGate, RejectsALoopFarOffAShortDriftFreePath) {
  // The cafe's false loops: 0.23 m and 6.9 degrees off after 2.1 m of path.
  const auto poses = straight_path(3);
  const SE3 odometry(SO3(), Vec3(2.0, 0.0, 0.0));
  const auto turned = check_loop_drift(poses, 0, 2, odometry * yaw(6.9 * kDeg, Vec3::Zero()));
  EXPECT_FALSE(turned.plausible);
  EXPECT_NEAR(turned.rotation_rad, 6.9 * kDeg, 1e-9);
  const auto shifted = check_loop_drift(poses, 0, 2, odometry * yaw(0.0, Vec3(0.0, 0.23, 0.0)));
  EXPECT_FALSE(shifted.plausible);
  EXPECT_NEAR(shifted.translation_m, 0.23, 1e-9);
}

TEST(LoopGate, KeepsTheDriftOfALongPath) {
  // ugv-loop's true loops: 0.2 m and 0.7 degrees after 70 m; uav-zigzag's: 1.0 m and 3.3
  // degrees after 108 m.
  const auto poses = straight_path(109);
  const SE3 at70(SO3(), Vec3(70.0, 0.0, 0.0));
  EXPECT_TRUE(
      check_loop_drift(poses, 0, 70, at70 * yaw(0.7 * kDeg, Vec3(0.0, 0.2, 0.0))).plausible);
  const SE3 at108(SO3(), Vec3(108.0, 0.0, 0.0));
  EXPECT_TRUE(
      check_loop_drift(poses, 0, 108, at108 * yaw(3.3 * kDeg, Vec3(0.0, 1.0, 0.0))).plausible);
  // ... but not a drift no odometry builds over that path.
  EXPECT_FALSE(check_loop_drift(poses, 0, 108, at108 * yaw(15.0 * kDeg, Vec3::Zero())).plausible);
}

TEST(LoopGate, DisabledKeepsEveryLoopAndUnknownPosesAreRejected) {
  const auto poses = straight_path(3);
  LoopGateOptions off;
  off.enabled = false;
  const SE3 wild = yaw(90.0 * kDeg, Vec3(5.0, 5.0, 0.0));
  EXPECT_TRUE(check_loop_drift(poses, 0, 2, wild, off).plausible);
  EXPECT_FALSE(check_loop_drift(poses, 0, 7, SE3()).plausible);
}

TEST(LoopGate, ARestartBetweenTheKeyframesIsSpanned) {
  const std::set<PoseId> restarts = {5, 9};
  EXPECT_TRUE(spans_restart(restarts, 2, 5));  // the restart keyframe itself: the jump is into it
  EXPECT_TRUE(spans_restart(restarts, 7, 3));
  EXPECT_TRUE(spans_restart(restarts, 6, 12));
  EXPECT_FALSE(spans_restart(restarts, 5, 8));  // from the restart on, the odometry is whole
  EXPECT_FALSE(spans_restart(restarts, 1, 4));
  EXPECT_FALSE(spans_restart(restarts, 10, 20));
  EXPECT_FALSE(spans_restart({}, 0, 100));
}

TEST(LoopGate, RestartSpanIsBlindWhenAnySpannedRestartHeldNothing) {
  const std::set<PoseId> restarts = {5, 9};
  const std::set<PoseId> blind = {9};
  EXPECT_EQ(restart_span(restarts, blind, 1, 4), RestartSpan::kNone);
  EXPECT_EQ(restart_span(restarts, blind, 2, 6), RestartSpan::kAttitudeHeld);
  EXPECT_EQ(restart_span(restarts, blind, 2, 12), RestartSpan::kBlind);
  EXPECT_EQ(restart_span(restarts, blind, 12, 7), RestartSpan::kBlind);
}

// A loop across a bridged loss: the position jumped there (5 m off is no evidence), the
// attitude did not (36 degrees off is a false match), a blind restart cannot judge either.
TEST(LoopGate, AcrossARestartTheIMUsAttitudeStillJudgesTheLoop) {
  const auto poses = straight_path(20);
  const SE3 odometry = poses.at(2).inverse() * poses.at(12);
  const LoopGateResult moved =
      check_loop_drift(poses, 2, 12, odometry * yaw(0.3 * kDeg, Vec3(5.0, 0.0, 0.0)));
  const LoopGateResult turned =
      check_loop_drift(poses, 2, 12, odometry * yaw(36.0 * kDeg, Vec3(0.5, 0.0, 0.0)));
  ASSERT_FALSE(moved.plausible);
  ASSERT_FALSE(turned.plausible);
  EXPECT_FALSE(accept_loop(moved, RestartSpan::kNone));
  EXPECT_TRUE(accept_loop(moved, RestartSpan::kAttitudeHeld));
  EXPECT_FALSE(accept_loop(turned, RestartSpan::kAttitudeHeld));
  EXPECT_TRUE(accept_loop(turned, RestartSpan::kBlind));
  const LoopGateResult agrees = check_loop_drift(poses, 2, 12, odometry);
  for (const RestartSpan s :
       {RestartSpan::kNone, RestartSpan::kAttitudeHeld, RestartSpan::kBlind}) {
    EXPECT_TRUE(accept_loop(agrees, s));
  }
}

}  // namespace
}  // namespace kestrel::loop
