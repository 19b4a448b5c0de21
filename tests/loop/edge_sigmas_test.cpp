#include "loop/edge_sigmas.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace kestrel::loop {
namespace {

TEST(EdgeSigmas, OdometryGrowsWithItsStepAndALoopHasItsOwn) {
  const EdgeSigmas s;
  const PoseGraphEdge still = odometry_edge(1, 2, SE3());
  EXPECT_EQ(still.kind, EdgeKind::kSequential);
  EXPECT_DOUBLE_EQ(still.sigma_translation, s.odometry_translation_floor_m);
  EXPECT_DOUBLE_EQ(still.sigma_rotation, s.odometry_rotation_floor_rad);
  const PoseGraphEdge step = odometry_edge(2, 3, SE3(Quat::Identity(), Vec3(0.3, 0.4, 0.0)));
  EXPECT_DOUBLE_EQ(step.sigma_translation,
                   s.odometry_translation_floor_m + 0.5 * s.odometry_translation_per_m);
  EXPECT_DOUBLE_EQ(step.sigma_rotation,
                   s.odometry_rotation_floor_rad + 0.5 * s.odometry_rotation_per_m_rad);
  EXPECT_EQ(step.from, 2);
  EXPECT_EQ(step.to, 3);
  const PoseGraphEdge loop = loop_edge(7, 90, SE3(Quat::Identity(), Vec3(5, 0, 0)));
  EXPECT_EQ(loop.kind, EdgeKind::kLoop);
  EXPECT_DOUBLE_EQ(loop.sigma_translation, s.loop_translation_m);
  EXPECT_DOUBLE_EQ(loop.sigma_rotation, s.loop_rotation_rad);
}

TEST(EdgeSigmas, RejectsSigmasThatAreNotPositive) {
  EdgeSigmas s;
  s.odometry_translation_floor_m = 0.0;
  try {
    odometry_edge(0, 1, SE3(), s);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("odometry_translation_floor_m"), std::string::npos);
  }
  s = EdgeSigmas{};
  s.odometry_rotation_per_m_rad = -1.0;
  EXPECT_THROW(odometry_edge(0, 1, SE3(), s), std::invalid_argument);
  s = EdgeSigmas{};
  s.loop_rotation_rad = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(loop_edge(0, 1, SE3(), s), std::invalid_argument);
  EXPECT_THROW(validate(s), std::invalid_argument);
  EXPECT_NO_THROW(validate(EdgeSigmas{}));
  s = EdgeSigmas{};
  s.odometry_translation_per_m = 0.0;  // a floor alone is allowed
  EXPECT_NO_THROW(odometry_edge(0, 1, SE3(), s));
}

// A hover (20 keyframes 5 mm apart) and then 10 m of flight (20 keyframes 0.5 m apart) whose
// odometry drifted 0.2 m, closed by a loop back to the start. One pair of sigmas for every edge
// hands each edge an equal share of the correction, so the hover, whose odometry is as good as
// exact, takes half of it and is pulled 0.1 m apart; weighed by their steps, the flight takes
// it, as much of it as the loop's sigma against the flight's gives.
TEST(EdgeSigmas, ALoopsCorrectionGoesWhereTheOdometryIsLeastSure) {
  std::vector<SE3> truth;
  for (int k = 0; k < 20; ++k) truth.emplace_back(SO3(), Vec3(0.0, 0.0, k % 2 == 0 ? 0.0 : 0.005));
  for (int k = 1; k <= 20; ++k) truth.emplace_back(SO3(), Vec3(0.5 * k, 0.0, 0.0));
  const auto n = static_cast<PoseId>(truth.size());
  const auto at = [&](PoseId i) { return truth[static_cast<std::size_t>(i)]; };
  std::map<PoseId, SE3> initial;
  std::vector<PoseGraphEdge> equal;
  std::vector<PoseGraphEdge> weighted;
  initial[0] = at(0);
  for (PoseId i = 1; i < n; ++i) {
    SE3 measured = at(i - 1).inverse() * at(i);
    if (i > 20) measured = measured * SE3(Quat::Identity(), Vec3(0.01, 0.0, 0.0));  // 2% long
    equal.push_back({i - 1, i, measured, EdgeKind::kSequential});
    weighted.push_back(odometry_edge(i - 1, i, measured));
    initial[i] = initial[i - 1] * measured;
  }
  const SE3 loop = at(0).inverse() * at(n - 1);
  equal.push_back({0, n - 1, loop, EdgeKind::kLoop});
  weighted.push_back(loop_edge(0, n - 1, loop));
  const auto hover_spread = [&](const std::map<PoseId, SE3>& poses) {
    double spread = 0.0;
    for (PoseId i = 1; i < 20; ++i)
      spread = std::max(spread, (poses.at(i).translation() - poses.at(0).translation()).norm());
    return spread;
  };
  const auto end_error = [&](const std::map<PoseId, SE3>& poses) {
    return (poses.at(n - 1).translation() - at(n - 1).translation()).norm();
  };
  const PoseGraphResult e = optimize_pose_graph(initial, equal, {0});
  const PoseGraphResult w = optimize_pose_graph(initial, weighted, {0});
  ASSERT_TRUE(w.converged);
  std::printf(
      "end error %.3f m; hover spread / end error after the loop: %.3f / %.4f m (one "
      "sigma pair), %.4f / %.4f m (EdgeSigmas)\n",
      end_error(initial), hover_spread(e.poses), end_error(e.poses), hover_spread(w.poses),
      end_error(w.poses));
  EXPECT_GT(end_error(initial), 0.18);
  EXPECT_GT(hover_spread(e.poses), 0.05);
  EXPECT_LT(hover_spread(w.poses), 0.01);
  // One loop as sure as the flight's odometry (3 cm against 20 steps of 6 mm) takes about half
  // the drift off; the tens a revisit closes take the rest.
  EXPECT_LT(end_error(w.poses), 0.6 * end_error(initial));
}

// A 10 m square, one keyframe every 0.25 m, whose odometry drifts 0.2 degrees of yaw per metre
// (more than EdgeSigmas allows for) and a loop back to the start: still corrected.
TEST(EdgeSigmas, DriftIsStillCorrectedByTheLoop) {
  std::vector<SE3> truth;
  Vec3 p(0, 0, 0);
  double yaw = 0.0;
  for (int side = 0; side < 4; ++side) {
    for (int step = 0; step < 40; ++step) {
      truth.emplace_back(SO3::exp(Vec3(0, 0, yaw)), p);
      p += 0.25 * Vec3(std::cos(yaw), std::sin(yaw), 0.0);
    }
    yaw += M_PI / 2.0;
  }
  truth.emplace_back(SO3::exp(Vec3(0, 0, yaw)), p);
  const auto n = static_cast<PoseId>(truth.size());
  const auto at = [&](PoseId i) { return truth[static_cast<std::size_t>(i)]; };
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::map<PoseId, SE3> initial;
  std::vector<PoseGraphEdge> edges;
  initial[0] = at(0);
  for (PoseId i = 1; i < n; ++i) {
    Vec6 err;
    err << 0.002 * noise(rng), 0.002 * noise(rng), 0.002 * noise(rng), 0.0002 * noise(rng),
        0.0002 * noise(rng), 0.0035 * 0.25 + 0.0002 * noise(rng);
    const SE3 measured = at(i - 1).inverse() * at(i) * SE3::exp(err);
    edges.push_back(odometry_edge(i - 1, i, measured));
    initial[i] = initial[i - 1] * measured;
  }
  edges.push_back(loop_edge(0, n - 1, at(0).inverse() * at(n - 1)));
  const auto rmse = [&](const std::map<PoseId, SE3>& poses) {
    double sum = 0.0;
    for (const auto& [id, T] : poses) sum += (T.translation() - at(id).translation()).squaredNorm();
    return std::sqrt(sum / static_cast<double>(poses.size()));
  };
  const PoseGraphResult r = optimize_pose_graph(initial, edges, {0});
  ASSERT_TRUE(r.converged);
  std::printf("yaw drift 0.2 deg/m: RMSE %.3f m -> %.4f m\n", rmse(initial), rmse(r.poses));
  EXPECT_GT(rmse(initial), 0.3);
  EXPECT_LT(rmse(r.poses), 0.2 * rmse(initial));
}

}  // namespace
}  // namespace kestrel::loop
