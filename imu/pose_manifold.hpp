#pragma once
// Ceres manifold for an SE(3) pose stored as 7 doubles [tx ty tz qx qy qz qw] (Eigen's
// quaternion memory order), with the right perturbation of core/se3.hpp:
// x ⊞ ξ = T(x) · SE3::exp(ξ), ξ = [ρ; φ]. Cost functions on such a block can compute their
// Jacobian J in this tangent space and hand Ceres `ambient_from_tangent(J)`, which gives
// back exactly J once Ceres applies PlusJacobian. Any optimizer with SE3 blocks (IMU,
// bundle adjustment, pose graph) can share it.
#include <ceres/manifold.h>

#include "core/se3.hpp"

namespace kestrel::imu {

inline constexpr int kPoseParamSize = 7;

inline void pose_to_params(const SE3& T, double* x) {
  Eigen::Map<Vec3>{x} = T.translation();
  Eigen::Map<Quat>{x + 3} = T.quaternion();
}
inline SE3 params_to_pose(const double* x) {
  return SE3(Quat(Eigen::Map<const Quat>(x + 3)), Eigen::Map<const Vec3>(x));
}

// d(q ⊗ Exp(φ))/dφ at φ = 0 is 0.5·Q(q), with orthonormal columns for a unit q.
inline Eigen::Matrix<double, 4, 3> quaternion_plus_basis(const Quat& q) {
  Eigen::Matrix<double, 4, 3> Q;
  Q.topRows<3>() = q.w() * Mat3::Identity() + SO3::hat(q.vec());
  Q.bottomRows<1>() = -q.vec().transpose();
  return Q;
}

// Lifts a tangent Jacobian (rows x 6, columns [ρ φ]) to the 7 ambient parameters of the
// pose at x, using the pseudo-inverse of PlusJacobian: [J_ρ Rᵀ, 2 J_φ Qᵀ].
template <int Rows>
void ambient_from_tangent(const Eigen::Matrix<double, Rows, 6>& J_tangent, const double* x,
                          double* J_ambient_row_major) {
  const SE3 T = params_to_pose(x);
  Eigen::Map<Eigen::Matrix<double, Rows, 7, Eigen::RowMajor>> J(J_ambient_row_major);
  J.template leftCols<3>() = J_tangent.template leftCols<3>() * T.rotation().transpose();
  J.template rightCols<4>() =
      2.0 * J_tangent.template rightCols<3>() * quaternion_plus_basis(T.quaternion()).transpose();
}

class PoseManifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return 7; }
  int TangentSize() const override { return 6; }

  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    pose_to_params(params_to_pose(x) * SE3::exp(Eigen::Map<const Vec6>(delta)), x_plus_delta);
    return true;
  }
  bool PlusJacobian(const double* x, double* jacobian) const override {
    const SE3 T = params_to_pose(x);
    Eigen::Map<Eigen::Matrix<double, 7, 6, Eigen::RowMajor>> J(jacobian);
    J.setZero();
    J.topLeftCorner<3, 3>() = T.rotation();
    J.bottomRightCorner<4, 3>() = 0.5 * quaternion_plus_basis(T.quaternion());
    return true;
  }
  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    Eigen::Map<Vec6>{y_minus_x} = (params_to_pose(x).inverse() * params_to_pose(y)).log();
    return true;
  }
  bool MinusJacobian(const double* x, double* jacobian) const override {
    const SE3 T = params_to_pose(x);
    Eigen::Map<Eigen::Matrix<double, 6, 7, Eigen::RowMajor>> J(jacobian);
    J.setZero();
    J.topLeftCorner<3, 3>() = T.rotation().transpose();
    J.bottomRightCorner<3, 4>() = 2.0 * quaternion_plus_basis(T.quaternion()).transpose();
    return true;
  }
};

}  // namespace kestrel::imu
