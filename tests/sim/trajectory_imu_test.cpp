// The IMU must be the exact derivative of the trajectory: integrating noiseless readings from
// the true state for 1 s has to land on the true pose (1 mm, 0.01 deg), and the analytic
// velocity / acceleration have to match finite differences of the pose.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "sim/imu_synthesizer.hpp"
#include "sim/spline_trajectory.hpp"

namespace kestrel::sim {
namespace {

SplineTrajectory test_trajectory() {
  std::vector<TrajectoryKnot> knots;
  const double deg = M_PI / 180.0;
  knots.push_back({Vec3(0, 0, 1.0), 0.0, 0.0, 0.0});
  knots.push_back({Vec3(1.0, 0.5, 1.2), 40 * deg, 5 * deg, -3 * deg});
  knots.push_back({Vec3(2.0, -0.3, 1.5), 120 * deg, -8 * deg, 6 * deg});
  knots.push_back({Vec3(1.5, -1.5, 1.1), 200 * deg, 3 * deg, 0.0});
  knots.push_back({Vec3(0.0, -1.0, 1.0), 280 * deg, 0.0, -4 * deg});
  Wobble w;
  w.terms.push_back({0, 0.02, 0.9, 0.3});
  w.terms.push_back({2, 0.015, 1.7, 1.1});
  w.terms.push_back({3, 0.03, 1.3, 0.2});
  w.terms.push_back({4, 0.02, 2.1, 2.0});
  w.terms.push_back({5, 0.025, 0.7, 0.5});
  return SplineTrajectory(knots, 0.8, w);
}

struct State {
  Quat q;
  Vec3 v, p;
};
struct Deriv {
  Vec3 omega_b, acc_b;
};

// dq/dt = q (0, w)/2, dv/dt = R a + g, dp/dt = v.
void rates(const State& s, const Deriv& d, Vec4& dq, Vec3& dv, Vec3& dp) {
  const Quat w(0, d.omega_b.x(), d.omega_b.y(), d.omega_b.z());
  const Quat qd = s.q * w;
  dq = 0.5 * qd.coeffs();
  dv = s.q * d.acc_b + Vec3(0, 0, -kGravity);
  dp = s.v;
}

State step(const State& s, double h, const Vec4& dq, const Vec3& dv, const Vec3& dp) {
  State o;
  o.q.coeffs() = s.q.coeffs() + h * dq;
  o.v = s.v + h * dv;
  o.p = s.p + h * dp;
  return o;
}

TEST(ImuSynthesizer, NoiselessIntegrationOverOneSecondEndsOnTheTruth) {
  const SplineTrajectory traj = test_trajectory();
  const double rate = 200.0, t0 = 1.3;
  std::vector<ImuSample> imu;
  for (int i = 0; i <= 200; ++i) {
    const double t = t0 + i / rate;
    imu.push_back(ImuSynthesizer::ideal(traj.state(t), from_seconds(t)));
  }
  const BodyState s0 = traj.state(t0);
  State s{s0.T_w_b.quaternion(), s0.v_w, s0.T_w_b.translation()};
  // RK4 with step 2/rate: samples k, k+1, k+2 give the start, middle and end of each step.
  const double h = 2.0 / rate;
  for (std::size_t k = 0; k + 2 < imu.size(); k += 2) {
    const Deriv a{imu[k].gyro, imu[k].acc}, m{imu[k + 1].gyro, imu[k + 1].acc},
        b{imu[k + 2].gyro, imu[k + 2].acc};
    Vec4 q1, q2, q3, q4;
    Vec3 v1, v2, v3, v4, p1, p2, p3, p4;
    rates(s, a, q1, v1, p1);
    rates(step(s, h / 2, q1, v1, p1), m, q2, v2, p2);
    rates(step(s, h / 2, q2, v2, p2), m, q3, v3, p3);
    rates(step(s, h, q3, v3, p3), b, q4, v4, p4);
    s.q.coeffs() += h / 6 * (q1 + 2 * q2 + 2 * q3 + q4);
    s.q.normalize();
    s.v += h / 6 * (v1 + 2 * v2 + 2 * v3 + v4);
    s.p += h / 6 * (p1 + 2 * p2 + 2 * p3 + p4);
  }
  const BodyState s1 = traj.state(t0 + 1.0);
  const double pos_err = (s.p - s1.T_w_b.translation()).norm();
  const double rot_err_deg = (SO3(s.q).inverse() * s1.T_w_b.so3()).log().norm() * 180.0 / M_PI;
  EXPECT_LT(pos_err, 1e-3);
  EXPECT_LT(rot_err_deg, 0.01);
  // The body really moved, so the check is not trivially met.
  EXPECT_GT((s1.T_w_b.translation() - s0.T_w_b.translation()).norm(), 0.3);
  EXPECT_GT((s0.T_w_b.so3().inverse() * s1.T_w_b.so3()).log().norm(), 0.5);
}

// The state's velocity, acceleration and angular velocity against central differences at t.
void expect_derivatives_match(const SplineTrajectory& traj, double t) {
  const double h = 1e-5;
  const BodyState a = traj.state(t - h), b = traj.state(t + h), c = traj.state(t);
  const Vec3 v_fd = (b.T_w_b.translation() - a.T_w_b.translation()) / (2 * h);
  const Vec3 a_fd = (b.v_w - a.v_w) / (2 * h);
  const Vec3 w_fd = (a.T_w_b.so3().inverse() * b.T_w_b.so3()).log() / (2 * h);
  EXPECT_LT((v_fd - c.v_w).norm(), 1e-6) << t;
  EXPECT_LT((a_fd - c.a_w).norm(), 1e-4) << t;
  EXPECT_LT((w_fd - c.omega_b).norm(), 1e-6) << t;
}

TEST(SplineTrajectory, AnalyticDerivativesMatchFiniteDifferences) {
  const SplineTrajectory traj = test_trajectory();
  for (double t : {0.3, 1.0, 2.2, 3.9}) expect_derivatives_match(traj, t);
}

// A take-off: on the pad (0.3 m) for a while, then up to 3 m, with a hovering drone's wobble
// that fades in between 0.3 and 1.3 m.
SplineTrajectory take_off(bool fade) {
  Wobble w;
  w.terms.push_back({0, 0.05, 0.9, 0.3});
  w.terms.push_back({2, 0.05, 1.5, 1.1});
  w.terms.push_back({3, 0.02, 1.3, 0.2});
  w.terms.push_back({4, 0.02, 2.1, 2.0});
  if (fade) {
    w.fade_z_still = 0.3;
    w.fade_z_full = 1.3;
  }
  return SplineTrajectory({{Vec3(0, 0, 0.3), 0.0, 0.0, 0.0},
                           {Vec3(0, 0, 0.3), 0.0, 0.0, 0.0},
                           {Vec3(0, 0, 3.0), 0.0, 0.0, 0.0},
                           {Vec3(2, 0, 3.0), 0.0, 0.0, 0.0}},
                          1.0, w);
}

TEST(SplineTrajectory, WobbleFadesOutOnThePadAndStaysDifferentiable) {
  const SplineTrajectory faded = take_off(true), full = take_off(false);
  // On the pad the body does not move at all; without the fade it bobs by centimetres.
  double still = 0.0, bob = 0.0;
  for (double t = 0.0; t <= 1.0; t += 0.01) {
    const BodyState s = faded.state(t);
    still = std::max({still, (s.T_w_b.translation() - Vec3(0, 0, 0.3)).norm(),
                      s.T_w_b.so3().log().norm(), s.v_w.norm(), s.a_w.norm(), s.omega_b.norm()});
    bob = std::max(bob, (full.state(t).T_w_b.translation() - Vec3(0, 0, 0.3)).norm());
  }
  EXPECT_LT(still, 1e-9);
  EXPECT_GT(bob, 0.03);
  // High up, the fade changes nothing.
  for (double t : {3.2, 3.6}) {
    const BodyState a = faded.state(t), b = full.state(t);
    EXPECT_LT((a.T_w_b.translation() - b.T_w_b.translation()).norm(), 1e-12) << t;
    EXPECT_LT((a.a_w - b.a_w).norm(), 1e-9) << t;
  }
  // In the fade band (the climb) the IMU's velocity and acceleration are still the exact
  // derivatives: the chain rule through the height-dependent amplitude.
  int in_band = 0;
  for (double t = 1.2; t < 3.0; t += 0.13) {
    const double z = faded.state(t).T_w_b.translation().z();
    in_band += z > 0.4 && z < 1.2;
    expect_derivatives_match(faded, t);
  }
  EXPECT_GE(in_band, 3);
}

TEST(SplineTrajectory, StartsAtRestOnTheFirstKnotAndHoldsTheEnd) {
  const SplineTrajectory traj({{Vec3(1, 2, 3), 0.5, 0, 0}, {Vec3(4, 2, 3), 1.0, 0, 0}}, 1.0);
  const BodyState s0 = traj.state(0.0);
  EXPECT_LT((s0.T_w_b.translation() - Vec3(1, 2, 3)).norm(), 1e-12);
  EXPECT_LT(s0.v_w.norm(), 1e-12);
  const BodyState s1 = traj.state(traj.duration() + 5.0);
  EXPECT_LT((s1.T_w_b.translation() - Vec3(4, 2, 3)).norm(), 1e-12);
  EXPECT_LT(s1.v_w.norm() + s1.a_w.norm() + s1.omega_b.norm(), 1e-12);
}

TEST(ImuSynthesizer, AtRestMeasuresGravityUpAndNoiseHasTheConfiguredSpread) {
  const SplineTrajectory still({{Vec3::Zero(), 0.3, 0.0, 0.0}}, 1.0);
  const ImuSample ideal = ImuSynthesizer::ideal(still.state(0.5), 0);
  EXPECT_NEAR(ideal.acc.z(), kGravity, 1e-12);
  EXPECT_LT(ideal.gyro.norm(), 1e-12);

  ImuNoise noise;
  ImuSynthesizer synth(noise, 42, true);
  const int n = 20000;
  double sum2 = 0.0;
  for (int i = 0; i < n; ++i) {
    const ImuSample s = synth.sample(still.state(0.0), i);
    sum2 += (s.gyro.x() - synth.gyro_bias().x()) * (s.gyro.x() - synth.gyro_bias().x());
  }
  const double expected = noise.gyro_noise * std::sqrt(noise.rate_hz);
  EXPECT_NEAR(std::sqrt(sum2 / n), expected, 0.05 * expected);
  // The bias walked: sigma after 100 s is gyro_walk * 10.
  EXPECT_GT(synth.gyro_bias().norm(), 0.0);
  EXPECT_LT(synth.gyro_bias().norm(), 10 * noise.gyro_walk * 10);
}

}  // namespace
}  // namespace kestrel::sim
