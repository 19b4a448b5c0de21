#include "imu/inertial_local_ba.hpp"

#include <ceres/problem.h>

#include <algorithm>
#include <array>
#include <memory>

#include "imu/imu_factor.hpp"
#include "imu/pose_manifold.hpp"

namespace kestrel::imu {

// With T_w_b = T_c_w⁻¹ T_c_b, a left perturbation δ of T_c_w is the right perturbation
// ξ = -Ad(T_b_c) δ of T_w_b, so the factor's tangent Jacobians carry over by that one matrix.
CameraImuFactor::CameraImuFactor(const PreintegratedImu& pre, const Vec3& gravity,
                                 const SE3& T_body_camera)
    : factor_(pre, gravity), T_c_b_(T_body_camera.inverse()), d_xi_(-T_body_camera.adjoint()) {}

bool CameraImuFactor::Evaluate(double const* const* params, double* residuals,
                               double** jacobians) const {
  std::array<double, 7> pose_i{}, pose_j{};
  pose_to_params(SE3::exp(Eigen::Map<const Vec6>(params[0])).inverse() * T_c_b_, pose_i.data());
  pose_to_params(SE3::exp(Eigen::Map<const Vec6>(params[4])).inverse() * T_c_b_, pose_j.data());
  const double* p[6] = {pose_i.data(), params[1], params[2], params[3], pose_j.data(), params[5]};
  ImuFactor::TangentJacobians J;
  const Vec9 r = factor_.raw_residual(p, jacobians ? &J : nullptr);
  const Mat9& S = factor_.sqrt_info();
  Eigen::Map<Vec9>{residuals} = S * r;
  if (jacobians) {
    using Mat96R = Eigen::Matrix<double, 9, 6, Eigen::RowMajor>;
    using Mat93R = Eigen::Matrix<double, 9, 3, Eigen::RowMajor>;
    if (jacobians[0]) Eigen::Map<Mat96R>{jacobians[0]} = S * J.pose_i * d_xi_;
    if (jacobians[1]) Eigen::Map<Mat93R>{jacobians[1]} = S * J.v_i;
    if (jacobians[2]) Eigen::Map<Mat93R>{jacobians[2]} = S * J.bg_i;
    if (jacobians[3]) Eigen::Map<Mat93R>{jacobians[3]} = S * J.ba_i;
    if (jacobians[4]) Eigen::Map<Mat96R>{jacobians[4]} = S * J.pose_j * d_xi_;
    if (jacobians[5]) Eigen::Map<Mat93R>{jacobians[5]} = S * J.v_j;
  }
  return r.allFinite();
}

namespace {

PreintegratedImu with_floor(PreintegratedImu pre, const InertialBaOptions& o) {
  const double rel = o.rotation_relative * SO3(pre.delta_R).angle();
  const double r2 = o.rotation_floor_rad * o.rotation_floor_rad + rel * rel;
  pre.covariance.block<3, 3>(0, 0) += r2 * Mat3::Identity();
  pre.covariance.block<3, 3>(3, 3) += o.velocity_floor * o.velocity_floor * Mat3::Identity();
  pre.covariance.block<3, 3>(6, 6) += o.position_floor * o.position_floor * Mat3::Identity();
  return pre;
}

}  // namespace

mapping::LocalBaSolution solve_inertial_local_ba(const mapping::LocalBaProblem& pb,
                                                 const PinholeCamera& camera,
                                                 const mapping::LocalBaOptions& options,
                                                 const InertialBaOptions& io) {
  if (pb.inertial.empty()) return mapping::solve_local_ba(pb, camera, options);
  // Velocity and bias blocks live here, across both stages of the solve.
  std::map<mapping::KeyframeId, Vec3> v_w = pb.v_w;
  const auto newest = std::max_element(pb.inertial.begin(), pb.inertial.end(),
                                       [](const auto& a, const auto& b) { return a.to < b.to; });
  const Vec3 bg0 = newest->imu.bias_gyro, ba0 = newest->imu.bias_acc;
  Vec3 bg = bg0, ba = ba0;
  std::vector<std::unique_ptr<ceres::CostFunction>> owned;  // the problem does not own them
  auto add = [&](ceres::CostFunction* cost) {
    owned.emplace_back(cost);
    return cost;
  };
  auto terms = [&](ceres::Problem& problem, std::map<mapping::KeyframeId, Vec6>& poses) {
    for (const auto& e : pb.inertial) {
      const auto from = poses.find(e.from);
      const auto to = poses.find(e.to);
      if (from == poses.end() || to == poses.end()) continue;
      problem.AddResidualBlock(
          add(new CameraImuFactor(with_floor(e.imu, io), e.gravity, e.T_body_camera)), nullptr,
          from->second.data(), v_w[e.from].data(), bg.data(), ba.data(), to->second.data(),
          v_w[e.to].data());
    }
    if (problem.HasParameterBlock(bg.data())) {
      problem.AddResidualBlock(add(new Vec3PriorFactor(bg0, io.gyro_bias_sigma)), nullptr,
                               bg.data());
      problem.AddResidualBlock(add(new Vec3PriorFactor(ba0, io.acc_bias_sigma)), nullptr,
                               ba.data());
    }
  };
  mapping::LocalBaSolution sol = mapping::solve_local_ba(pb, camera, options, terms);
  for (const auto& [k, v] : v_w) {
    if (!pb.fixed.count(k) && v.allFinite()) sol.v_w[k] = v;
  }
  return sol;
}

}  // namespace kestrel::imu
