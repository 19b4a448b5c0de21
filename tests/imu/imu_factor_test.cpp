#include "imu/imu_factor.hpp"

#include <ceres/problem.h>
#include <ceres/solver.h>
#include <gtest/gtest.h>

#include <array>

#include "tests/imu/imu_test_motion.hpp"

namespace kestrel::imu {
namespace {

using test::Motion;

// Parameter blocks of one ImuFactor, stored so that pointers stay valid.
struct Blocks {
  std::array<double, 7> pose_i, pose_j;
  Vec3 v_i, v_j, bg, ba;
  std::array<const double*, 6> ptrs() const {
    return {pose_i.data(), v_i.data(), bg.data(), ba.data(), pose_j.data(), v_j.data()};
  }
};

Preintegration make_pre(const Motion& m, double t0, double t1, const ImuBias& b) {
  Preintegration pre(b, ImuNoise{});
  const auto s = m.samples(t0, t1, 200.0);
  pre.integrate(s, from_seconds(t0), from_seconds(t1));
  return pre;
}

Blocks blocks_at(const Motion& m, double t0, double t1, const ImuBias& b) {
  Blocks x;
  const NavState i = m.state(t0), j = m.state(t1);
  pose_to_params(SE3(i.R, i.p), x.pose_i.data());
  pose_to_params(SE3(j.R, j.p), x.pose_j.data());
  x.v_i = i.v;
  x.v_j = j.v;
  x.bg = b.gyro;
  x.ba = b.acc;
  return x;
}

TEST(PoseManifold, PlusMinusAndJacobians) {
  const PoseManifold M;
  std::array<double, 7> x;
  pose_to_params(SE3(SO3::exp(Vec3(0.3, -1.2, 0.8)), Vec3(1, 2, 3)), x.data());
  Vec6 d;
  d << 0.1, -0.2, 0.3, 0.05, 0.2, -0.1;
  std::array<double, 7> y;
  ASSERT_TRUE(M.Plus(x.data(), d.data(), y.data()));
  Vec6 back;
  ASSERT_TRUE(M.Minus(y.data(), x.data(), back.data()));
  EXPECT_LT((back - d).norm(), 1e-12);

  Eigen::Matrix<double, 7, 6, Eigen::RowMajor> J;
  ASSERT_TRUE(M.PlusJacobian(x.data(), J.data()));
  const double eps = 1e-6;
  for (int k = 0; k < 6; ++k) {
    Vec6 e = Vec6::Zero();
    e(k) = eps;
    std::array<double, 7> p, m;
    M.Plus(x.data(), e.data(), p.data());
    e(k) = -eps;
    M.Plus(x.data(), e.data(), m.data());
    for (int r = 0; r < 7; ++r) EXPECT_NEAR((p[r] - m[r]) / (2 * eps), J(r, k), 1e-8);
  }
  Eigen::Matrix<double, 6, 7, Eigen::RowMajor> Jm;
  ASSERT_TRUE(M.MinusJacobian(x.data(), Jm.data()));
  EXPECT_LT((Jm * J - Mat6::Identity()).norm(), 1e-12);
}

TEST(ImuFactor, ResidualIsSmallAtTheTrueStates) {
  Motion m;
  m.gyro_bias = Vec3(0.01, 0.02, -0.01);
  m.acc_bias = Vec3(0.1, -0.05, 0.2);
  const ImuBias b{m.gyro_bias, m.acc_bias};
  const Preintegration pre = make_pre(m, 0.2, 0.7, b);
  const ImuFactor f(pre, m.gravity);
  const Blocks x = blocks_at(m, 0.2, 0.7, b);
  const Vec9 r = f.raw_residual(x.ptrs().data(), nullptr);
  EXPECT_LT(r.head<3>().norm(), 2e-6);
  EXPECT_LT(r.segment<3>(3).norm(), 2e-5);
  EXPECT_LT(r.tail<3>().norm(), 1e-5);
}

// Every analytic block (tangent space) against central differences through the manifold.
TEST(ImuFactor, AnalyticJacobiansMatchNumericDifferences) {
  Motion m;
  const ImuBias b0{Vec3(0.01, -0.02, 0.01), Vec3(0.1, 0.05, -0.1)};
  const Preintegration pre = make_pre(m, 0.4, 1.1, b0);
  const ImuFactor f(pre, m.gravity);
  // Away from the solution and from the linearization bias, so that every term is active.
  Blocks x = blocks_at(m, 0.4, 1.1, b0);
  {
    const PoseManifold M;
    Vec6 d;
    d << 0.05, -0.03, 0.02, 0.04, -0.06, 0.03;
    std::array<double, 7> tmp;
    M.Plus(x.pose_j.data(), d.data(), tmp.data());
    x.pose_j = tmp;
  }
  x.v_i += Vec3(0.1, -0.2, 0.05);
  x.bg += Vec3(0.003, -0.002, 0.004);
  x.ba += Vec3(-0.02, 0.03, 0.01);

  ImuFactor::TangentJacobians J;
  const Vec9 r0 = f.raw_residual(x.ptrs().data(), &J);
  ASSERT_GT(r0.norm(), 1e-3);

  const PoseManifold M;
  const double eps = 1e-6;
  auto numeric_pose = [&](int block) {
    Eigen::Matrix<double, 9, 6> N;
    for (int k = 0; k < 6; ++k) {
      Blocks p = x, q = x;
      Vec6 e = Vec6::Zero();
      e(k) = eps;
      auto& dst_p = block == 0 ? p.pose_i : p.pose_j;
      auto& dst_q = block == 0 ? q.pose_i : q.pose_j;
      const auto& src = block == 0 ? x.pose_i : x.pose_j;
      M.Plus(src.data(), e.data(), dst_p.data());
      e(k) = -eps;
      M.Plus(src.data(), e.data(), dst_q.data());
      N.col(k) =
          (f.raw_residual(p.ptrs().data(), nullptr) - f.raw_residual(q.ptrs().data(), nullptr)) /
          (2 * eps);
    }
    return N;
  };
  auto numeric_vec = [&](Vec3 Blocks::*member) {
    Mat93 N;
    for (int k = 0; k < 3; ++k) {
      Blocks p = x, q = x;
      (p.*member)(k) += eps;
      (q.*member)(k) -= eps;
      N.col(k) =
          (f.raw_residual(p.ptrs().data(), nullptr) - f.raw_residual(q.ptrs().data(), nullptr)) /
          (2 * eps);
    }
    return N;
  };
  auto check = [](const auto& analytic, const auto& numeric, const char* name) {
    const double err = (analytic - numeric).norm();
    EXPECT_LT(err, 1e-6 * std::max(1.0, numeric.norm())) << name << "\nanalytic\n"
                                                         << analytic << "\nnumeric\n"
                                                         << numeric;
  };
  check(J.pose_i, numeric_pose(0), "pose_i");
  check(J.pose_j, numeric_pose(1), "pose_j");
  check(J.v_i, numeric_vec(&Blocks::v_i), "v_i");
  check(J.v_j, numeric_vec(&Blocks::v_j), "v_j");
  check(J.bg_i, numeric_vec(&Blocks::bg), "bg");
  check(J.ba_i, numeric_vec(&Blocks::ba), "ba");

  // What Ceres sees: whitened residual, ambient Jacobians that map back to the tangent ones
  // through PlusJacobian.
  Vec9 res;
  Eigen::Matrix<double, 9, 7, Eigen::RowMajor> Ji, Jj;
  Eigen::Matrix<double, 9, 3, Eigen::RowMajor> Jvi, Jbg, Jba, Jvj;
  double* jac[6] = {Ji.data(), Jvi.data(), Jbg.data(), Jba.data(), Jj.data(), Jvj.data()};
  ASSERT_TRUE(f.Evaluate(x.ptrs().data(), res.data(), jac));
  EXPECT_LT((res - f.sqrt_info() * r0).norm(), 1e-9 * res.norm());
  Eigen::Matrix<double, 7, 6, Eigen::RowMajor> Pi, Pj;
  M.PlusJacobian(x.pose_i.data(), Pi.data());
  M.PlusJacobian(x.pose_j.data(), Pj.data());
  const double scale = f.sqrt_info().norm();
  EXPECT_LT((Ji * Pi - f.sqrt_info() * J.pose_i).norm(), 1e-9 * scale);
  EXPECT_LT((Jj * Pj - f.sqrt_info() * J.pose_j).norm(), 1e-9 * scale);
  EXPECT_LT((Jbg - f.sqrt_info() * J.bg_i).norm(), 1e-9 * scale);
}

TEST(ImuFactor, SqrtInformationWhitensTheCovariance) {
  Motion m;
  const Preintegration pre = make_pre(m, 0.0, 0.5, {});
  const Mat9 S = sqrt_information(pre.covariance());
  EXPECT_LT((S * pre.covariance() * S.transpose() - Mat9::Identity()).norm(), 1e-6);
  // A zero covariance (empty interval) still gives finite weights.
  EXPECT_TRUE(sqrt_information(Mat9::Zero()).allFinite());
}

// The factor in a real Ceres problem: with state i and the biases fixed, solving for a
// perturbed state j lands on the pre-integration prediction.
TEST(ImuFactor, CeresRecoversThePredictedState) {
  Motion m;
  const ImuBias b{Vec3(0.01, 0.0, -0.01), Vec3(0.0, 0.1, 0.0)};
  m.gyro_bias = b.gyro;
  m.acc_bias = b.acc;
  const Preintegration pre = make_pre(m, 1.0, 1.5, b);
  Blocks x = blocks_at(m, 1.0, 1.5, b);
  const NavState pred = pre.predict(m.state(1.0), m.gravity);
  pose_to_params(SE3(SO3::exp(Vec3(0.1, -0.1, 0.2)) * pred.R, pred.p + Vec3(0.3, -0.2, 0.1)),
                 x.pose_j.data());
  x.v_j += Vec3(0.5, 0.5, -0.5);

  ceres::Problem problem;
  problem.AddResidualBlock(new ImuFactor(pre, m.gravity), nullptr, x.pose_i.data(), x.v_i.data(),
                           x.bg.data(), x.ba.data(), x.pose_j.data(), x.v_j.data());
  problem.SetManifold(x.pose_i.data(), new PoseManifold);
  problem.SetManifold(x.pose_j.data(), new PoseManifold);
  for (double* p : {x.pose_i.data(), x.v_i.data(), x.bg.data(), x.ba.data()}) {
    problem.SetParameterBlockConstant(p);
  }
  ceres::Solver::Options opt;
  opt.max_num_iterations = 20;
  ceres::Solver::Summary summary;
  ceres::Solve(opt, &problem, &summary);
  ASSERT_TRUE(summary.IsSolutionUsable());
  const SE3 Tj = params_to_pose(x.pose_j.data());
  EXPECT_LT((Tj.so3().inverse() * pred.R).log().norm(), 1e-8);
  EXPECT_LT((Tj.translation() - pred.p).norm(), 1e-8);
  EXPECT_LT((x.v_j - pred.v).norm(), 1e-8);
}

TEST(BiasWalkFactor, WeightsAndJacobians) {
  ImuNoise noise;
  const double dt = 0.25;
  const BiasWalkFactor f(noise, dt);
  Vec3 bgi(0.01, 0.02, 0.03), bai(0.1, 0.2, 0.3), bgj(0.011, 0.02, 0.03), baj(0.1, 0.2, 0.31);
  const double* params[4] = {bgi.data(), bai.data(), bgj.data(), baj.data()};
  Vec6 r;
  Eigen::Matrix<double, 6, 3, Eigen::RowMajor> J[4];
  double* jac[4] = {J[0].data(), J[1].data(), J[2].data(), J[3].data()};
  ASSERT_TRUE(f.Evaluate(params, r.data(), jac));
  EXPECT_NEAR(r(0), 0.001 / (noise.gyro_walk * std::sqrt(dt)), 1e-9);
  EXPECT_NEAR(r(5), 0.01 / (noise.acc_walk * std::sqrt(dt)), 1e-9);
  Vec3* blocks[4] = {&bgi, &bai, &bgj, &baj};
  for (int b = 0; b < 4; ++b) {
    for (int k = 0; k < 3; ++k) {
      const double eps = 1e-6;
      (*blocks[b])(k) += eps;
      Vec6 rp;
      f.Evaluate(params, rp.data(), nullptr);
      (*blocks[b])(k) -= 2 * eps;
      Vec6 rm;
      f.Evaluate(params, rm.data(), nullptr);
      (*blocks[b])(k) += eps;
      EXPECT_LT(((rp - rm) / (2 * eps) - J[b].col(k)).norm(), 1e-4 * J[b].norm());
    }
  }
}

}  // namespace
}  // namespace kestrel::imu
