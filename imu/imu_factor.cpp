#include "imu/imu_factor.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace kestrel::imu {

Mat9 sqrt_information(const Mat9& cov) {
  const Mat9 sym = 0.5 * (cov + cov.transpose());
  Eigen::SelfAdjointEigenSolver<Mat9> es(sym);
  const Vec9 ev = es.eigenvalues();
  const double floor = std::max(ev.maxCoeff() * 1e-12, 1e-30);
  Vec9 inv_sqrt;
  for (int k = 0; k < 9; ++k) {
    const double e = std::isfinite(ev(k)) ? std::max(ev(k), floor) : floor;
    inv_sqrt(k) = 1.0 / std::sqrt(e);
  }
  return inv_sqrt.asDiagonal() * es.eigenvectors().transpose();
}

ImuFactor::ImuFactor(const Preintegration& pre, const Vec3& gravity)
    : ImuFactor(pre.summary(), gravity) {}

ImuFactor::ImuFactor(const PreintegratedImu& pre, const Vec3& gravity)
    : dR_(SO3(pre.delta_R)),
      dv_(pre.delta_v),
      dp_(pre.delta_p),
      dt_(pre.dt),
      bias0_{pre.bias_gyro, pre.bias_acc},
      J_R_bg_(pre.dR_dbg),
      J_v_bg_(pre.dv_dbg),
      J_v_ba_(pre.dv_dba),
      J_p_bg_(pre.dp_dbg),
      J_p_ba_(pre.dp_dba),
      gravity_(gravity),
      sqrt_info_(sqrt_information(pre.covariance)) {}

Vec9 ImuFactor::raw_residual(double const* const* parameters, TangentJacobians* J) const {
  const SE3 Ti = params_to_pose(parameters[0]);
  const Eigen::Map<const Vec3> vi(parameters[1]);
  const Eigen::Map<const Vec3> bg(parameters[2]);
  const Eigen::Map<const Vec3> ba(parameters[3]);
  const SE3 Tj = params_to_pose(parameters[4]);
  const Eigen::Map<const Vec3> vj(parameters[5]);

  const Vec3 dbg = bg - bias0_.gyro;
  const Vec3 dba = ba - bias0_.acc;
  const Vec3 bg_step = J_R_bg_ * dbg;
  const SO3 dR_corr = dR_ * SO3::exp(bg_step);
  const Vec3 dv_corr = dv_ + J_v_bg_ * dbg + J_v_ba_ * dba;
  const Vec3 dp_corr = dp_ + J_p_bg_ * dbg + J_p_ba_ * dba;

  const Mat3 RiT = Ti.rotation().transpose();
  const SO3 E = dR_corr.inverse() * Ti.so3().inverse() * Tj.so3();
  const Vec3 rR = E.log();
  const Vec3 dv_world = vj - vi - gravity_ * dt_;
  const Vec3 dp_world = Tj.translation() - Ti.translation() - vi * dt_ - 0.5 * gravity_ * dt_ * dt_;
  const Vec3 v_body = RiT * dv_world;
  const Vec3 p_body = RiT * dp_world;

  Vec9 r;
  r << rR, v_body - dv_corr, p_body - dp_corr;
  if (J == nullptr) return r;

  const Mat3 Jr_inv = SO3::right_jacobian_inverse(rR);
  const Mat3 RjT_Ri = Tj.rotation().transpose() * Ti.rotation();
  J->pose_i.setZero();
  J->pose_i.block<3, 3>(0, 3) = -Jr_inv * RjT_Ri;
  J->pose_i.block<3, 3>(3, 3) = SO3::hat(v_body);
  J->pose_i.block<3, 3>(6, 0) = -Mat3::Identity();
  J->pose_i.block<3, 3>(6, 3) = SO3::hat(p_body);

  J->pose_j.setZero();
  J->pose_j.block<3, 3>(0, 3) = Jr_inv;
  J->pose_j.block<3, 3>(6, 0) = RiT * Tj.rotation();

  J->v_i.setZero();
  J->v_i.block<3, 3>(3, 0) = -RiT;
  J->v_i.block<3, 3>(6, 0) = -dt_ * RiT;
  J->v_j.setZero();
  J->v_j.block<3, 3>(3, 0) = RiT;

  J->bg_i.block<3, 3>(0, 0) =
      -Jr_inv * E.matrix().transpose() * SO3::right_jacobian(bg_step) * J_R_bg_;
  J->bg_i.block<3, 3>(3, 0) = -J_v_bg_;
  J->bg_i.block<3, 3>(6, 0) = -J_p_bg_;
  J->ba_i.setZero();
  J->ba_i.block<3, 3>(3, 0) = -J_v_ba_;
  J->ba_i.block<3, 3>(6, 0) = -J_p_ba_;
  return r;
}

bool ImuFactor::Evaluate(double const* const* parameters, double* residuals,
                         double** jacobians) const {
  TangentJacobians J;
  const Vec9 r = raw_residual(parameters, jacobians != nullptr ? &J : nullptr);
  Eigen::Map<Vec9>{residuals} = sqrt_info_ * r;
  if (jacobians == nullptr) return r.allFinite();

  using Mat93R = Eigen::Matrix<double, 9, 3, Eigen::RowMajor>;
  if (jacobians[0] != nullptr) {
    ambient_from_tangent<9>(Eigen::Matrix<double, 9, 6>(sqrt_info_ * J.pose_i), parameters[0],
                            jacobians[0]);
  }
  if (jacobians[1] != nullptr) Eigen::Map<Mat93R>{jacobians[1]} = sqrt_info_ * J.v_i;
  if (jacobians[2] != nullptr) Eigen::Map<Mat93R>{jacobians[2]} = sqrt_info_ * J.bg_i;
  if (jacobians[3] != nullptr) Eigen::Map<Mat93R>{jacobians[3]} = sqrt_info_ * J.ba_i;
  if (jacobians[4] != nullptr) {
    ambient_from_tangent<9>(Eigen::Matrix<double, 9, 6>(sqrt_info_ * J.pose_j), parameters[4],
                            jacobians[4]);
  }
  if (jacobians[5] != nullptr) Eigen::Map<Mat93R>{jacobians[5]} = sqrt_info_ * J.v_j;
  return r.allFinite();
}

BiasWalkFactor::BiasWalkFactor(const ImuNoise& noise, double dt) {
  // A zero-length interval would give an infinite weight; a microsecond floor keeps it finite.
  const double t = std::max(dt, 1e-6);
  w_gyro_ = 1.0 / (std::max(noise.gyro_walk, 1e-12) * std::sqrt(t));
  w_acc_ = 1.0 / (std::max(noise.acc_walk, 1e-12) * std::sqrt(t));
}

bool BiasWalkFactor::Evaluate(double const* const* parameters, double* residuals,
                              double** jacobians) const {
  const Eigen::Map<const Vec3> bg_i(parameters[0]);
  const Eigen::Map<const Vec3> ba_i(parameters[1]);
  const Eigen::Map<const Vec3> bg_j(parameters[2]);
  const Eigen::Map<const Vec3> ba_j(parameters[3]);
  Eigen::Map<Vec3>{residuals} = w_gyro_ * (bg_j - bg_i);
  Eigen::Map<Vec3>{residuals + 3} = w_acc_ * (ba_j - ba_i);
  if (jacobians == nullptr) return true;
  using Mat63R = Eigen::Matrix<double, 6, 3, Eigen::RowMajor>;
  const double w[4] = {-w_gyro_, -w_acc_, w_gyro_, w_acc_};
  for (int k = 0; k < 4; ++k) {
    if (jacobians[k] == nullptr) continue;
    Eigen::Map<Mat63R> J(jacobians[k]);
    J.setZero();
    J.block<3, 3>(k % 2 == 0 ? 0 : 3, 0) = w[k] * Mat3::Identity();
  }
  return true;
}

bool Vec3PriorFactor::Evaluate(double const* const* parameters, double* residuals,
                               double** jacobians) const {
  Eigen::Map<Vec3>{residuals} = w_ * (Eigen::Map<const Vec3>(parameters[0]) - mean_);
  if (jacobians && jacobians[0]) {
    Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>{jacobians[0]} = w_ * Mat3::Identity();
  }
  return true;
}

}  // namespace kestrel::imu
