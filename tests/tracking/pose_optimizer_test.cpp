#include "tracking/pose_optimizer.hpp"

#include <gtest/gtest.h>

#include <random>

#include "tracking/matcher.hpp"
#include "tracking/pnp.hpp"

namespace kestrel::tracking {
namespace {

PinholeCamera camera() {
  PinholeCamera c;
  c.fx = 525.0;
  c.fy = 525.0;
  c.cx = 319.5;
  c.cy = 239.5;
  return c;
}

TEST(PoseOptimizer, AnalyticJacobianMatchesNumeric) {
  const PinholeCamera cam = camera();
  const SE3 T(SO3::exp(Vec3(0.2, -0.3, 0.1)), Vec3(0.3, -0.1, 0.5));
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < 20; ++k) {
    const Vec3 p_w = T.inverse() * Vec3(u(rng), u(rng), 2.5 + u(rng));
    const Vec2 uv(300 + 50 * u(rng), 200 + 50 * u(rng));
    Vec2 r;
    Mat26 J;
    ASSERT_TRUE(pose_residual(cam, T, p_w, uv, &r, &J));
    Mat26 Jn;
    constexpr double h = 1e-6;
    for (int j = 0; j < 6; ++j) {
      Vec6 d = Vec6::Zero();
      d[j] = h;
      Vec2 rp, rm;
      ASSERT_TRUE(pose_residual(cam, SE3::exp(d) * T, p_w, uv, &rp));
      ASSERT_TRUE(pose_residual(cam, SE3::exp(-d) * T, p_w, uv, &rm));
      Jn.col(j) = (rp - rm) / (2 * h);
    }
    EXPECT_LT((J - Jn).norm(), 1e-5 * (1.0 + J.norm())) << "J\n" << J << "\nnumeric\n" << Jn;
  }
}

struct Scene {
  std::vector<Vec3> points_w;
  std::vector<Vec2> uv;
  std::vector<bool> outlier;
};

// Points in front of the true camera, observed with Gaussian pixel noise; a fraction replaced
// by random pixels (wrong matches).
Scene make_scene(const PinholeCamera& cam, const SE3& T_c_w, int n, double noise_px,
                 double outlier_fraction, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(0, cam.width), uy(0, cam.height), uz(1.0, 6.0),
      u01(0, 1);
  std::normal_distribution<double> noise(0.0, noise_px);
  Scene s;
  const SE3 T_w_c = T_c_w.inverse();
  for (int i = 0; i < n; ++i) {
    const Vec2 px(ux(rng), uy(rng));
    const Vec3 p_c = cam.unproject(px) * uz(rng);
    s.points_w.push_back(T_w_c * p_c);
    const bool out = u01(rng) < outlier_fraction;
    s.outlier.push_back(out);
    s.uv.push_back(out ? Vec2(ux(rng), uy(rng)) : Vec2(px + Vec2(noise(rng), noise(rng))));
  }
  return s;
}

double rotation_error_deg(const SE3& a, const SE3& b) {
  return (a.so3().inverse() * b.so3()).angle() * 180.0 / M_PI;
}
double translation_error(const SE3& a, const SE3& b) {
  // Camera centres, the quantity a trajectory error measures.
  return (a.inverse().translation() - b.inverse().translation()).norm();
}

TEST(PoseOptimizer, PnpThenOptimizationRecoverPoseWithNoiseAndOutliers) {
  const PinholeCamera cam = camera();
  const SE3 T_c_w(SO3::exp(Vec3(0.1, 0.4, -0.2)), Vec3(0.5, -0.2, 1.0));
  const Scene s = make_scene(cam, T_c_w, 600, 0.5, 0.2, 11);
  const auto pnp = solve_pnp_ransac(cam, s.points_w, s.uv);
  ASSERT_TRUE(pnp.has_value());
  EXPECT_GT(pnp->inliers, 400);
  EXPECT_LT(translation_error(pnp->T_c_w, T_c_w), 0.05);

  std::vector<PoseObservation> obs;
  for (std::size_t i = 0; i < s.points_w.size(); ++i) obs.push_back({s.points_w[i], s.uv[i], 1.0});
  const PoseOptimizerResult r = optimize_pose(cam, obs, pnp->T_c_w);
  ASSERT_TRUE(r.ok);
  EXPECT_LT(translation_error(r.T_c_w, T_c_w), 1e-3);
  EXPECT_LT(rotation_error_deg(r.T_c_w, T_c_w), 0.05);
  int correct = 0, inliers = 0;
  for (std::size_t i = 0; i < obs.size(); ++i) {
    inliers += r.inlier[i];
    correct += (r.inlier[i] != 0) == !s.outlier[i] ? 1 : 0;
  }
  EXPECT_GT(correct, static_cast<int>(0.97 * obs.size()));
  EXPECT_EQ(inliers, r.inliers);
}

TEST(PoseOptimizer, ConvergesFromAPerturbedPrior) {
  const PinholeCamera cam = camera();
  const SE3 T_c_w(SO3::exp(Vec3(-0.05, 0.1, 0.02)), Vec3(-0.3, 0.1, 0.2));
  const Scene s = make_scene(cam, T_c_w, 300, 1.0, 0.1, 5);
  std::vector<PoseObservation> obs;
  for (std::size_t i = 0; i < s.points_w.size(); ++i) obs.push_back({s.points_w[i], s.uv[i], 1.0});
  Vec6 d;
  d << 0.05, -0.03, 0.04, 0.02, -0.02, 0.03;  // 7 cm, 2.5 degrees off
  const PoseOptimizerResult r = optimize_pose(cam, obs, SE3::exp(d) * T_c_w);
  ASSERT_TRUE(r.ok);
  EXPECT_LT(translation_error(r.T_c_w, T_c_w), 3e-3);
  EXPECT_LT(rotation_error_deg(r.T_c_w, T_c_w), 0.1);
}

PosePrior prior_at(const SE3& T_c_w, double sigma_t, double sigma_r) {
  PosePrior p;
  p.T_c_w = T_c_w;
  p.information.diagonal() << Vec3::Constant(1.0 / (sigma_t * sigma_t)),
      Vec3::Constant(1.0 / (sigma_r * sigma_r));
  return p;
}

TEST(PoseOptimizer, PriorHoldsThePoseThatFewPointsCannot) {
  // Twelve points on one far plane leave translation along the view and rotation nearly
  // interchangeable; a prior from the IMU fixes what they cannot.
  const PinholeCamera cam = camera();
  const SE3 T_c_w(SO3::exp(Vec3(0.02, -0.05, 0.01)), Vec3(0.1, 0.0, -0.2));
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<PoseObservation> obs;
  for (int i = 0; i < 12; ++i) {
    const Vec2 px(280 + 8 * i, 230 + (i % 3) * 10);
    const Vec3 p_w = T_c_w.inverse() * (cam.unproject(px) * 12.0);
    obs.push_back({p_w, px + Vec2(n(rng), n(rng)), 1.0});
  }
  Vec6 d;
  d << 0.004, -0.003, 0.003, 0.0005, 0.0005, -0.0005;  // what the IMU is off by
  const PosePrior prior = prior_at(SE3::exp(d) * T_c_w, 0.01, 0.002);
  PoseOptimizerOptions o;
  o.min_inliers = 6;
  const PoseOptimizerResult with = optimize_pose(cam, obs, prior.T_c_w, o, &prior);
  ASSERT_TRUE(with.ok);
  EXPECT_LT(translation_error(with.T_c_w, T_c_w), 0.01);
  EXPECT_LT(rotation_error_deg(with.T_c_w, T_c_w), 0.1);
  const PoseOptimizerResult without = optimize_pose(cam, obs, prior.T_c_w, o);
  const double e_without = without.ok ? translation_error(without.T_c_w, T_c_w) : 1e9;
  EXPECT_GT(e_without, 2.0 * translation_error(with.T_c_w, T_c_w))
      << "the points alone should not pin the pose: " << e_without << " m";
}

TEST(PoseOptimizer, ManyGoodPointsOutweighAWrongPrior) {
  const PinholeCamera cam = camera();
  const SE3 T_c_w(SO3::exp(Vec3(-0.05, 0.1, 0.02)), Vec3(-0.3, 0.1, 0.2));
  const Scene s = make_scene(cam, T_c_w, 300, 1.0, 0.0, 9);
  std::vector<PoseObservation> obs;
  for (std::size_t i = 0; i < s.points_w.size(); ++i) obs.push_back({s.points_w[i], s.uv[i], 1.0});
  Vec6 d;
  d << 0.03, 0.0, -0.02, 0.0, 0.01, 0.0;  // 3.6 cm, 0.6 degrees: a drifting IMU
  const PosePrior prior = prior_at(SE3::exp(d) * T_c_w, 0.005, 0.001);
  const PoseOptimizerResult r = optimize_pose(cam, obs, prior.T_c_w, {}, &prior);
  ASSERT_TRUE(r.ok);
  EXPECT_LT(translation_error(r.T_c_w, T_c_w), 3e-3);
  EXPECT_LT(rotation_error_deg(r.T_c_w, T_c_w), 0.05);
}

TEST(PoseOptimizer, TheFramesOwnDepthPinsWhatFarPointsLeaveOpen) {
  // Sixty points on one small patch 6 m away: moving along the view barely changes where they
  // project (15 cm there is under a pixel), so reprojection alone leaves the distance to the
  // patch to the pixel noise. Their depth, read by the frame itself with a D455's noise
  // (0.003 z^2, 11 cm there), pins it.
  const PinholeCamera cam = camera();
  const SE3 T_c_w(SO3::exp(Vec3(0.02, -0.05, 0.01)), Vec3(0.1, 0.0, -0.2));
  std::mt19937 rng(4);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<PoseObservation> obs;
  for (int i = 0; i < 60; ++i) {
    const Vec2 px(260 + 10 * (i % 12), 220 + 10 * (i / 12));
    const double z = 6.0 + 0.05 * n(rng);
    obs.push_back({T_c_w.inverse() * (cam.unproject(px) * z), px + Vec2(n(rng), n(rng)), 1.0,
                   z + 0.003 * z * z * n(rng)});
  }
  // The camera centre's error along the view, in the true camera's frame.
  const auto along_view = [&](const SE3& T) {
    return std::abs((T_c_w * T.inverse().translation()).z());
  };
  Vec6 d;
  d << 0.0, 0.0, 0.15, 0.0, 0.0, 0.0;  // 15 cm along the view
  PoseOptimizerOptions o;
  o.min_inliers = 6;
  o.virtual_bf = 333.0;
  const PoseOptimizerResult with = optimize_pose(cam, obs, SE3::exp(d) * T_c_w, o);
  ASSERT_TRUE(with.ok);
  EXPECT_LT(along_view(with.T_c_w), 0.04);
  o.virtual_bf = 0.0;
  const PoseOptimizerResult without = optimize_pose(cam, obs, SE3::exp(d) * T_c_w, o);
  const double e_without = without.ok ? along_view(without.T_c_w) : 1e9;
  EXPECT_GT(e_without, 3.0 * along_view(with.T_c_w))
      << "reprojection alone should not pin the distance: " << e_without << " m";
}

TEST(PoseOptimizer, AnObservationWhoseDepthDisagreesIsAnOutlier) {
  // A walker between the camera and the point: the pixel matches, the depth does not.
  const PinholeCamera cam = camera();
  const SE3 T_c_w(SO3::exp(Vec3(-0.05, 0.1, 0.02)), Vec3(-0.3, 0.1, 0.2));
  const Scene s = make_scene(cam, T_c_w, 200, 0.5, 0.0, 13);
  std::vector<PoseObservation> obs;
  for (std::size_t i = 0; i < s.points_w.size(); ++i) {
    obs.push_back({s.points_w[i], s.uv[i], 1.0, (T_c_w * s.points_w[i]).z()});
  }
  obs[7].depth *= 0.6;
  PoseOptimizerOptions o;
  o.virtual_bf = 333.0;
  const PoseOptimizerResult r = optimize_pose(cam, obs, T_c_w, o);
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.inlier[7], 0);
  EXPECT_GE(r.inliers, 195);
  EXPECT_LT(translation_error(r.T_c_w, T_c_w), 2e-3);
  o.virtual_bf = 0.0;  // pixels alone cannot tell
  EXPECT_EQ(optimize_pose(cam, obs, T_c_w, o).inlier[7], 1);
}

TEST(PoseOptimizer, TooFewObservationsIsNotOkAndKeepsTheInitialPose) {
  const PinholeCamera cam = camera();
  const SE3 T;
  const Scene s = make_scene(cam, T, 5, 0.5, 0.0, 3);
  std::vector<PoseObservation> obs;
  for (std::size_t i = 0; i < s.points_w.size(); ++i) obs.push_back({s.points_w[i], s.uv[i], 1.0});
  const SE3 init(SO3::exp(Vec3(0.01, 0, 0)), Vec3(0.1, 0, 0));
  const PoseOptimizerResult r = optimize_pose(cam, obs, init);
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(r.T_c_w.translation().isApprox(init.translation()));
  EXPECT_FALSE(solve_pnp_ransac(cam, s.points_w, s.uv).has_value());
}

TEST(Matcher, BruteForceFindsPerturbedCopiesAndRejectsAmbiguity) {
  std::mt19937_64 rng(3);
  std::vector<OrbDescriptor> train(200);
  for (auto& d : train) d.words = {rng(), rng(), rng(), rng()};
  std::vector<OrbDescriptor> query;
  for (int i = 0; i < 50; ++i) {
    OrbDescriptor d = train[static_cast<std::size_t>(i * 3)];
    d.words[0] ^= (1ull << (i % 64)) | (1ull << ((i + 7) % 64));  // 2 bits off
    query.push_back(d);
  }
  // A query exactly between two train descriptors is ambiguous.
  train.push_back(train[10]);
  const auto m = match_brute_force(query, train);
  for (int i = 0; i < 50; ++i) {
    if (i * 3 == 10) continue;
    EXPECT_EQ(m[static_cast<std::size_t>(i)], i * 3);
  }
}

}  // namespace
}  // namespace kestrel::tracking
