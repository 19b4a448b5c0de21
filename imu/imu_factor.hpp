#pragma once
// Ceres residuals for the inertial edge between two states (Forster et al. 2017, eq. 45) and
// for the bias random walk. Included only by optimization code: it pulls in Ceres.
//
// Parameter blocks of ImuFactor: pose_i [7, PoseManifold], v_i [3, world], bg_i [3], ba_i [3],
// pose_j [7, PoseManifold], v_j [3]. Residual [r_R, r_v, r_p] whitened by the square-root
// information of the pre-integration covariance. Jacobians are analytic.
#include <ceres/sized_cost_function.h>

#include "imu/pose_manifold.hpp"
#include "imu/preintegration.hpp"

namespace kestrel::imu {

// S with Sᵀ S = cov⁻¹; eigenvalues below a relative floor are clamped so that a degenerate
// (e.g. zero-length) interval gives a finite, very stiff weight instead of NaN.
Mat9 sqrt_information(const Mat9& cov);

class ImuFactor final : public ceres::SizedCostFunction<9, 7, 3, 3, 3, 7, 3> {
 public:
  explicit ImuFactor(const Preintegration& pre, const Vec3& gravity = gravity_vector());
  explicit ImuFactor(const PreintegratedImu& pre, const Vec3& gravity = gravity_vector());

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  // Unwhitened residual and its Jacobians in the tangent spaces ([ρ φ] for poses), for tests
  // and for callers that build their own problems.
  struct TangentJacobians {
    Eigen::Matrix<double, 9, 6> pose_i, pose_j;
    Mat93 v_i, v_j, bg_i, ba_i;
  };
  Vec9 raw_residual(double const* const* parameters, TangentJacobians* J) const;
  const Mat9& sqrt_info() const { return sqrt_info_; }

 private:
  SO3 dR_;
  Vec3 dv_, dp_;
  double dt_;
  ImuBias bias0_;
  Mat3 J_R_bg_, J_v_bg_, J_v_ba_, J_p_bg_, J_p_ba_;
  Vec3 gravity_;
  Mat9 sqrt_info_;
};

// Random walk of the biases over an interval dt: r = [bg_j - bg_i; ba_j - ba_i], whitened by
// sigma_walk * sqrt(dt). Blocks: bg_i, ba_i, bg_j, ba_j.
class BiasWalkFactor final : public ceres::SizedCostFunction<6, 3, 3, 3, 3> {
 public:
  BiasWalkFactor(const ImuNoise& noise, double dt);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  double w_gyro_, w_acc_;
};

// A Gaussian prior on a 3-vector block (a bias held near an earlier estimate): r = (x - mean) /
// sigma.
class Vec3PriorFactor final : public ceres::SizedCostFunction<3, 3> {
 public:
  Vec3PriorFactor(const Vec3& mean, double sigma) : mean_(mean), w_(1.0 / sigma) {}
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Vec3 mean_;
  double w_;
};

}  // namespace kestrel::imu
