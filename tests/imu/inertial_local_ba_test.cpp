#include "imu/inertial_local_ba.hpp"

#include <gtest/gtest.h>

#include <array>
#include <random>

#include "imu/preintegration.hpp"
#include "tests/imu/imu_test_motion.hpp"

namespace kestrel::imu {
namespace {

using test::Motion;

const SE3 kBodyCamera(SO3::exp(Vec3(-1.5, 0.05, -1.55)), Vec3(0.05, -0.02, 0.03));

PreintegratedImu pre_between(const Motion& m, double t0, double t1) {
  Preintegration pre(ImuBias{}, ImuNoise{});
  pre.integrate(m.samples(t0, t1, 200.0), from_seconds(t0), from_seconds(t1));
  return pre.summary();
}

Vec6 camera_xi(const Motion& m, double t) {
  const NavState s = m.state(t);
  return (SE3(s.R, s.p) * kBodyCamera).inverse().log();
}

TEST(CameraImuFactor, VanishesAtTheTrueStatesWithACameraOffTheBody) {
  const Motion m;
  const CameraImuFactor f(pre_between(m, 1.0, 1.4), m.gravity, kBodyCamera);
  Vec6 xi_i = camera_xi(m, 1.0), xi_j = camera_xi(m, 1.4);
  Vec3 v_i = m.velocity(1.0), v_j = m.velocity(1.4);
  const Vec3 zero = Vec3::Zero();
  const double* p[6] = {xi_i.data(), v_i.data(), zero.data(), zero.data(), xi_j.data(), v_j.data()};
  Vec9 r;
  ASSERT_TRUE(f.Evaluate(p, r.data(), nullptr));
  // Whitened: the midpoint integration's error is far below one sigma.
  EXPECT_LT(r.norm(), 0.05);
}

TEST(CameraImuFactor, JacobiansMatchNumericDifferencesOfTheLeftPerturbation) {
  const Motion m;
  const CameraImuFactor f(pre_between(m, 2.0, 2.5), m.gravity, kBodyCamera);
  // Away from the truth, so that every term of the Jacobian matters.
  std::array<Vec6, 2> xi = {camera_xi(m, 2.0), camera_xi(m, 2.5)};
  xi[0] = (SE3::exp((Vec6() << 0.02, -0.03, 0.01, 0.01, -0.02, 0.015).finished()) * SE3::exp(xi[0]))
              .log();
  std::array<Vec3, 2> v = {m.velocity(2.0) + Vec3(0.1, -0.05, 0.02), m.velocity(2.5)};
  const Vec3 bg(0.002, -0.001, 0.003), ba(0.05, 0.02, -0.04);
  const double* p[6] = {xi[0].data(), v[0].data(), bg.data(), ba.data(), xi[1].data(), v[1].data()};
  Vec9 r0;
  Eigen::Matrix<double, 9, 6, Eigen::RowMajor> Jxi_i, Jxi_j;
  Eigen::Matrix<double, 9, 3, Eigen::RowMajor> Jv_i, Jv_j, Jbg, Jba;
  double* J[6] = {Jxi_i.data(), Jv_i.data(), Jbg.data(), Jba.data(), Jxi_j.data(), Jv_j.data()};
  ASSERT_TRUE(f.Evaluate(p, r0.data(), J));

  const double eps = 1e-6;
  auto residual = [&](const std::array<Vec6, 2>& x, const std::array<Vec3, 2>& w) {
    const double* q[6] = {x[0].data(), w[0].data(), bg.data(), ba.data(), x[1].data(), w[1].data()};
    Vec9 r;
    f.Evaluate(q, r.data(), nullptr);
    return r;
  };
  for (int s = 0; s < 2; ++s) {
    const auto& Jxi = s == 0 ? Jxi_i : Jxi_j;
    const auto& Jv = s == 0 ? Jv_i : Jv_j;
    for (int k = 0; k < 6; ++k) {
      Vec6 d = Vec6::Zero();
      d(k) = eps;
      auto plus = xi, minus = xi;
      plus[s] = (SE3::exp(d) * SE3::exp(xi[s])).log();
      minus[s] = (SE3::exp(-d) * SE3::exp(xi[s])).log();
      const Vec9 num = (residual(plus, v) - residual(minus, v)) / (2 * eps);
      EXPECT_LT((num - Jxi.col(k)).norm(), 1e-4 * (1.0 + num.norm())) << "pose " << s << " " << k;
    }
    for (int k = 0; k < 3; ++k) {
      auto plus = v, minus = v;
      plus[s](k) += eps;
      minus[s](k) -= eps;
      const Vec9 num = (residual(xi, plus) - residual(xi, minus)) / (2 * eps);
      EXPECT_LT((num - Jv.col(k)).norm(), 1e-4 * (1.0 + num.norm()))
          << "velocity " << s << " " << k;
    }
  }
}

}  // namespace
}  // namespace kestrel::imu

namespace kestrel::imu {
namespace {

// Three keyframes 0.3 s apart; the first is fixed, the second sees 60 points, the third only
// two (a wall in the dark, a walker filling the view): vision cannot place it, the IMU can.
struct WeakKeyframeProblem {
  mapping::LocalBaProblem pb;
  std::array<SE3, 3> truth;  // T_c_w
};

WeakKeyframeProblem weak_keyframe_problem() {
  const Motion m;
  const std::array<double, 3> t = {1.0, 1.3, 1.6};
  WeakKeyframeProblem w;
  const PinholeCamera camera;
  for (int k = 0; k < 3; ++k) w.truth[k] = SE3::exp(camera_xi(m, t[k]));
  mapping::LocalBaProblem& pb = w.pb;
  pb.current = 2;
  pb.fixed = {0};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(-1.0, 1.0), uz(2.0, 4.0);
  int id = 0;
  for (int i = 0; i < 60; ++i) {
    const Vec3 p_c(ux(rng), 0.8 * ux(rng), uz(rng));
    const Vec3 p_w = w.truth[1].inverse() * p_c;
    std::array<std::optional<Vec2>, 3> uv;
    for (int k = 0; k < 3; ++k) uv[k] = camera.project(w.truth[k] * p_w);
    if (!uv[0] || !uv[1] || !uv[2]) continue;
    pb.points[id] = p_w;
    for (int k = 0; k < 3; ++k) {
      if (k == 2 && id >= 2) continue;  // the weak keyframe
      pb.observations.push_back({k, id, *uv[k], 1.0, 1.0, 0.0});
    }
    ++id;
  }
  for (int k = 0; k < 3; ++k) pb.T_c_w[k] = w.truth[k];
  // The weak keyframe starts 5 cm and a degree off, as a bad track would leave it.
  pb.T_c_w[2] =
      SE3::exp((Vec6() << 0.04, -0.03, 0.01, 0.01, -0.012, 0.006).finished()) * w.truth[2];
  for (int k = 0; k < 2; ++k) {
    pb.inertial.push_back({k, k + 1, pre_between(m, t[k], t[k + 1]), m.gravity, kBodyCamera});
  }
  for (int k = 0; k < 3; ++k) pb.v_w[k] = m.velocity(t[k]) + Vec3(0.05, -0.05, 0.02);
  return w;
}

double translation_error(const SE3& a, const SE3& b) {
  return (a.inverse().translation() - b.inverse().translation()).norm();
}

TEST(InertialLocalBa, PlacesAKeyframeThatVisionCannot) {
  const WeakKeyframeProblem w = weak_keyframe_problem();
  ASSERT_GE(w.pb.points.size(), 40u);
  const PinholeCamera camera;
  const mapping::LocalBaSolution visual = mapping::solve_local_ba(w.pb, camera);
  const mapping::LocalBaSolution inertial = solve_inertial_local_ba(w.pb, camera);
  ASSERT_TRUE(visual.T_c_w.count(2) && inertial.T_c_w.count(2));
  // Two points leave the pose free along most directions: vision leaves it about where it was.
  EXPECT_GT(translation_error(visual.T_c_w.at(2), w.truth[2]), 0.01);
  EXPECT_LT(translation_error(inertial.T_c_w.at(2), w.truth[2]), 0.005);
  EXPECT_LT((inertial.T_c_w.at(2) * w.truth[2].inverse()).so3().angle(), 1e-3);
  // The well-seen keyframe stays where vision has it.
  EXPECT_LT(translation_error(inertial.T_c_w.at(1), w.truth[1]), 0.005);
  // Velocities come out of the solve, nearer the truth than the IMU's guesses they started at.
  const Motion m;
  ASSERT_TRUE(inertial.v_w.count(2));
  EXPECT_LT((inertial.v_w.at(2) - m.velocity(1.6)).norm(), 0.03);
}

TEST(InertialLocalBa, WithoutEdgesIsTheVisualSolve) {
  WeakKeyframeProblem w = weak_keyframe_problem();
  w.pb.inertial.clear();
  const PinholeCamera camera;
  const auto a = mapping::solve_local_ba(w.pb, camera);
  const auto b = solve_inertial_local_ba(w.pb, camera);
  ASSERT_EQ(a.T_c_w.size(), b.T_c_w.size());
  for (const auto& [k, T] : a.T_c_w) EXPECT_LT((T.log() - b.T_c_w.at(k).log()).norm(), 1e-12);
  EXPECT_TRUE(b.v_w.empty());
}

}  // namespace
}  // namespace kestrel::imu
