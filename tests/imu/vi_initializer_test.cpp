#include <gtest/gtest.h>

#include <cstdio>
#include <limits>
#include <random>

#include "imu/imu_initializer.hpp"
#include "tests/imu/imu_test_motion.hpp"

namespace kestrel::imu {
namespace {

using test::Motion;

// A visual-only map of the Motion trajectory: camera poses in an arbitrary visual frame
// (tilted, so gravity is not along -z there) with translations divided by `metric_scale`.
struct Scenario {
  Motion motion;
  SE3 T_b_c;
  SE3 T_v_w;
  double metric_scale = 1.0;
  std::vector<double> stamps;
  std::vector<SE3> T_v_c;
  std::vector<Preintegration> pre;

  Scenario(double scale, bool noisy, unsigned seed = 7, bool moving = true) : metric_scale(scale) {
    if (!moving) {
      motion.rot_scale = 0.0;
      motion.pos_scale = 0.0;
    }
    motion.gyro_bias = Vec3(0.01, -0.02, 0.015);
    motion.acc_bias = Vec3(0.03, -0.02, 0.04);
    T_b_c = SE3(SO3::exp(Vec3(-1.2, 0.1, 1.5)), Vec3(0.05, 0.02, -0.01));
    T_v_w = SE3(SO3::exp(Vec3(0.4, -0.3, 1.1)), Vec3(0.5, -1.0, 2.0));
    for (int k = 0; k < 11; ++k) stamps.push_back(0.25 * k);
    for (double t : stamps) {
      const NavState s = motion.state(t);
      const SE3 T_v_c_metric = T_v_w * SE3(s.R, s.p) * T_b_c;
      T_v_c.emplace_back(T_v_c_metric.so3(), T_v_c_metric.translation() / metric_scale);
    }
    std::vector<ImuSample> imu = motion.samples(stamps.front(), stamps.back(), 200.0);
    ImuNoise noise;
    if (noisy) {
      std::mt19937 rng(seed);
      test::add_noise(imu, noise, 1.0 / 200.0, rng);
    }
    for (std::size_t k = 0; k + 1 < stamps.size(); ++k) {
      Preintegration p(ImuBias{}, noise);
      p.integrate(imu, from_seconds(stamps[k]), from_seconds(stamps[k + 1]));
      pre.push_back(p);
    }
  }

  double gravity_error_deg(const ViInitResult& r) const {
    const Vec3 down_true = T_v_w.so3() * Vec3(0, 0, -1);
    const Vec3 down_est = r.R_w_v.inverse() * Vec3(0, 0, -1);
    return std::acos(std::clamp(down_true.dot(down_est), -1.0, 1.0)) * 180.0 / M_PI;
  }
  double max_velocity_error(const ViInitResult& r) const {
    // World yaw is arbitrary: compare in the visual frame, where both are defined.
    double worst = 0.0;
    for (std::size_t k = 0; k < stamps.size(); ++k) {
      const Vec3 v_true = T_v_w.so3() * motion.velocity(stamps[k]);
      worst = std::max(worst, (r.R_w_v.inverse() * r.velocities[k] - v_true).norm());
    }
    return worst;
  }
};

void report(const char* name, const Scenario& s, const ViInitResult& r) {
  std::printf(
      "%s: gravity err %.4f deg, gyro bias err %.2e rad/s, scale %.4f (true %.4f, "
      "linear %.4f), acc bias err %.3f, max |v err| %.4f m/s, %d iterations\n",
      name, s.gravity_error_deg(r), (r.bias.gyro - s.motion.gyro_bias).norm(), r.scale,
      s.metric_scale, r.scale_linear, (r.bias.acc - s.motion.acc_bias).norm(),
      s.max_velocity_error(r), r.refine_iterations);
}

TEST(ViInitializer, MonocularRecoversGravityGyroBiasAndScale) {
  Scenario s(2.5, true);
  const ViInitResult r = visual_inertial_initialize(s.T_v_c, s.T_b_c, s.pre);
  ASSERT_TRUE(r.ok()) << to_string(r.status);
  report("mono", s, r);
  EXPECT_LT(s.gravity_error_deg(r), 0.5);
  EXPECT_LT((r.bias.gyro - s.motion.gyro_bias).norm(), 1e-3);
  EXPECT_NEAR(r.scale, s.metric_scale, 0.02 * s.metric_scale);
  EXPECT_LT(s.max_velocity_error(r), 0.05);
  // The pre-integrations were re-linearized at the estimate.
  EXPECT_LT((s.pre[0].bias().gyro - r.bias.gyro).norm(), 1e-12);

  // Recovered keyframe poses are metric and gravity-aligned: their relative motion matches.
  const SE3 A = r.body_pose(s.T_v_c[2], s.T_b_c), B = r.body_pose(s.T_v_c[7], s.T_b_c);
  const NavState a = s.motion.state(s.stamps[2]), b = s.motion.state(s.stamps[7]);
  EXPECT_NEAR((B.translation() - A.translation()).norm(), (b.p - a.p).norm(), 0.02);
  EXPECT_NEAR((B.translation() - A.translation()).z(), (b.p - a.p).z(), 0.03);
}

TEST(ViInitializer, MetricMapKeepsScaleFixed) {
  Scenario s(1.0, true, 11);
  ViInitOptions opt;
  opt.estimate_scale = false;
  const ViInitResult r = visual_inertial_initialize(s.T_v_c, s.T_b_c, s.pre, opt);
  ASSERT_TRUE(r.ok()) << to_string(r.status);
  report("metric", s, r);
  EXPECT_EQ(r.scale, 1.0);
  EXPECT_LT(s.gravity_error_deg(r), 0.5);
  EXPECT_LT((r.bias.gyro - s.motion.gyro_bias).norm(), 1e-3);
  EXPECT_LT(s.max_velocity_error(r), 0.05);
}

// Noise-free, so that what is left is model error: the linear step holds the accelerometer bias
// at zero and ignores |g|; the refinement estimates the one and enforces the other.
TEST(ViInitializer, RefinementImprovesOnTheLinearSolution) {
  Scenario s1(2.5, false), s2(2.5, false);
  ViInitOptions linear_only;
  linear_only.refine = false;
  const ViInitResult lin = visual_inertial_initialize(s1.T_v_c, s1.T_b_c, s1.pre, linear_only);
  const ViInitResult ref = visual_inertial_initialize(s2.T_v_c, s2.T_b_c, s2.pre);
  ASSERT_TRUE(lin.ok());
  ASSERT_TRUE(ref.ok());
  report("linear only", s1, lin);
  report("refined", s2, ref);
  EXPECT_LT(std::abs(ref.scale - 2.5), 0.5 * std::abs(lin.scale - 2.5));
  EXPECT_LT(s2.gravity_error_deg(ref), 0.5 * s1.gravity_error_deg(lin));
  EXPECT_LT((ref.bias.acc - s2.motion.acc_bias).norm(), 0.5 * s2.motion.acc_bias.norm());
}

TEST(ViInitializer, ReportsBadInput) {
  Scenario s(1.0, false);
  std::vector<SE3> three(s.T_v_c.begin(), s.T_v_c.begin() + 3);
  std::vector<Preintegration> two(s.pre.begin(), s.pre.begin() + 2);
  EXPECT_EQ(visual_inertial_initialize(three, s.T_b_c, two).status, ViInitStatus::kBadInput);
  // Mismatched counts.
  EXPECT_EQ(visual_inertial_initialize(s.T_v_c, s.T_b_c, two).status, ViInitStatus::kBadInput);
  // A non-finite pose.
  std::vector<SE3> bad = s.T_v_c;
  bad[3].translation().x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(visual_inertial_initialize(bad, s.T_b_c, s.pre).status, ViInitStatus::kBadInput);
  // Standing still, a monocular map has no scale to find.
  Scenario still(2.0, false, 1, false);
  EXPECT_EQ(visual_inertial_initialize(still.T_v_c, still.T_b_c, still.pre).status,
            ViInitStatus::kDegenerate);
}

}  // namespace
}  // namespace kestrel::imu
