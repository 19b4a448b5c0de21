#include "loop/pose_graph.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace kestrel::loop {
namespace {

// Ground truth: a 10 m square driven counter-clockwise, one pose per metre, camera looking
// along the direction of travel (body z forward, rotated about the world z axis).
std::vector<SE3> square_truth() {
  std::vector<SE3> poses;
  Vec3 p(0, 0, 0);
  double yaw = 0.0;
  for (int side = 0; side < 4; ++side) {
    for (int step = 0; step < 10; ++step) {
      poses.emplace_back(SO3::exp(Vec3(0, 0, yaw)), p);
      p += Vec3(std::cos(yaw), std::sin(yaw), 0.0);
    }
    yaw += M_PI / 2.0;
  }
  poses.emplace_back(SO3::exp(Vec3(0, 0, yaw)), p);  // back at the start, heading 2π
  return poses;
}

TEST(PoseGraph, SquareLoopWithDriftIsCorrected) {
  const std::vector<SE3> truth = square_truth();
  const int n = static_cast<int>(truth.size());
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 1.0);
  // Odometry: each relative motion with a systematic error (0.6° yaw, 0.2° roll, 2 % scale)
  // and noise, so that dead reckoning drifts in rotation and translation.
  std::map<PoseId, SE3> initial;
  std::vector<PoseGraphEdge> edges;
  initial[0] = truth[0];
  for (int i = 1; i < n; ++i) {
    const SE3 rel =
        truth[static_cast<std::size_t>(i - 1)].inverse() * truth[static_cast<std::size_t>(i)];
    Vec6 err;
    err << 0.02 * rel.translation().norm() + 0.005 * noise(rng), 0.005 * noise(rng),
        0.005 * noise(rng), 0.0035 + 0.001 * noise(rng), 0.001 * noise(rng),
        0.0105 + 0.001 * noise(rng);
    const SE3 measured = rel * SE3::exp(err);
    edges.push_back({i - 1, i, measured, EdgeKind::kSequential});
    initial[i] = initial[i - 1] * measured;
  }
  // The loop edge: the last pose seen again from the first (exact, as a verified loop gives).
  edges.push_back(
      {0, n - 1, truth[0].inverse() * truth[static_cast<std::size_t>(n - 1)], EdgeKind::kLoop});

  const double end_error_before =
      (initial[n - 1].translation() - truth.back().translation()).norm();
  const PoseGraphResult result = optimize_pose_graph(initial, edges, {0});
  ASSERT_TRUE(result.converged);
  EXPECT_LT(result.final_cost, 0.01 * result.initial_cost);
  const double end_error_after =
      (result.poses.at(n - 1).translation() - truth.back().translation()).norm();
  double max_error = 0.0;
  double max_rot_error = 0.0;
  double max_error_before = 0.0;
  for (int i = 0; i < n; ++i) {
    const auto& T = result.poses.at(i);
    const auto& G = truth[static_cast<std::size_t>(i)];
    max_error = std::max(max_error, (T.translation() - G.translation()).norm());
    max_rot_error = std::max(max_rot_error, (G.inverse() * T).log().tail<3>().norm());
    max_error_before =
        std::max(max_error_before, (initial.at(i).translation() - G.translation()).norm());
  }
  std::printf(
      "end-point error %.3f m -> %.4f m; max position error %.3f m -> %.3f m, "
      "max rotation error %.2f deg\n",
      end_error_before, end_error_after, max_error_before, max_error, max_rot_error * 180.0 / M_PI);
  EXPECT_GT(end_error_before, 2.0);  // the drift is real
  EXPECT_LT(end_error_after, 0.1 * end_error_before);
  EXPECT_LT(max_error, 0.35);
  EXPECT_LT(max_rot_error, 2.0 * M_PI / 180.0);
  EXPECT_TRUE(result.poses.at(0).translation().isApprox(truth[0].translation()));
}

// A loop edge aliased by periodic texture (the right view, a pose shifted by 2.5 m) next to
// correct loop edges: the Cauchy loss on loop edges keeps it from bending the trajectory.
TEST(PoseGraph, RobustLossWithstandsAnAliasedLoopEdge) {
  const std::vector<SE3> truth = square_truth();
  const auto n = static_cast<PoseId>(truth.size());
  std::map<PoseId, SE3> poses;
  std::vector<PoseGraphEdge> edges;
  const auto rel = [&](PoseId a, PoseId b) {
    return truth[static_cast<std::size_t>(a)].inverse() * truth[static_cast<std::size_t>(b)];
  };
  for (PoseId i = 0; i < n; ++i) poses[i] = truth[static_cast<std::size_t>(i)];
  for (PoseId i = 1; i < n; ++i) edges.push_back({i - 1, i, rel(i - 1, i), EdgeKind::kSequential});
  for (PoseId i : {10, 20, 30})
    edges.push_back({i - 10 + 2, i + 2, rel(i - 8, i + 2), EdgeKind::kLoop});
  edges.push_back({5, 25, rel(5, 25) * SE3(Quat::Identity(), Vec3(0, 0, 2.5)), EdgeKind::kLoop});
  const auto max_error = [&](const PoseGraphResult& r) {
    double e = 0.0;
    for (const auto& [id, T] : r.poses)
      e = std::max(e, (T.translation() - truth[static_cast<std::size_t>(id)].translation()).norm());
    return e;
  };
  PoseGraphOptions plain;
  PoseGraphOptions robust;
  robust.loop_loss_scale = 1.0;
  const double e_plain = max_error(optimize_pose_graph(poses, edges, {0}, plain));
  const double e_robust = max_error(optimize_pose_graph(poses, edges, {0}, robust));
  std::printf(
      "aliased loop edge: max position error %.3f m without a robust loss, %.3f m with Cauchy\n",
      e_plain, e_robust);
  EXPECT_GT(e_plain, 0.3);
  EXPECT_LT(e_robust, 0.5 * e_plain);
}

TEST(PoseGraph, ConsistentGraphStaysPutAndUnknownPosesAreIgnored) {
  const std::vector<SE3> truth = square_truth();
  std::map<PoseId, SE3> poses;
  std::vector<PoseGraphEdge> edges;
  for (std::size_t i = 0; i < truth.size(); ++i) poses[static_cast<PoseId>(i)] = truth[i];
  for (std::size_t i = 1; i < truth.size(); ++i)
    edges.push_back({static_cast<PoseId>(i - 1), static_cast<PoseId>(i),
                     truth[i - 1].inverse() * truth[i], EdgeKind::kSequential});
  edges.push_back({5, 999, SE3(), EdgeKind::kCovisibility});
  const PoseGraphResult result = optimize_pose_graph(poses, edges);
  for (const auto& [id, T] : result.poses)
    EXPECT_LT((T.translation() - poses.at(id).translation()).norm(), 1e-6);
  EXPECT_EQ(result.poses.size(), poses.size());
}

}  // namespace
}  // namespace kestrel::loop
