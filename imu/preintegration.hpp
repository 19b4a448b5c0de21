#pragma once
// On-manifold IMU pre-integration between two frames (Forster et al., "On-Manifold
// Preintegration for Real-Time Visual-Inertial Odometry", T-RO 2017), with midpoint
// integration: the gyro rate of a step is the average of its two samples and the specific
// force is averaged after rotating each sample into the start frame (trapezoid), which keeps
// the discretization error second order in the sample period.
//
// Perturbations follow Forster: ΔR(b) ≈ ΔR̂ Exp(J_R_bg δbg), Δv(b) ≈ Δv̂ + J_v_bg δbg + J_v_ba δba,
// and the 9x9 covariance is ordered [δφ, δv, δp] with δφ a right perturbation of ΔR.
#include <span>
#include <vector>

#include "core/imu.hpp"
#include "core/so3.hpp"
#include "imu/nav_state.hpp"

namespace kestrel::imu {

using Mat9 = Eigen::Matrix<double, 9, 9>;
using Vec9 = Eigen::Matrix<double, 9, 1>;
using Mat93 = Eigen::Matrix<double, 9, 3>;

class Preintegration {
 public:
  Preintegration() = default;
  Preintegration(const ImuBias& bias, const ImuNoise& noise) : bias_(bias), noise_(noise) {}

  // One midpoint step between two consecutive samples (b.t > a.t). Steps with a
  // non-positive or non-finite duration, or non-finite readings, are skipped and counted.
  void integrate(const ImuSample& a, const ImuSample& b);

  // Integrates exactly over [t0, t1]: the samples at the two ends are interpolated from their
  // neighbours. `samples` must be time-ordered. Returns false when they do not cover
  // [t0, t1]; the uncovered ends are then held at the nearest sample (what a caller can do
  // best with a late IMU packet) and the result is still usable.
  bool integrate(std::span<const ImuSample> samples, Timestamp t0, Timestamp t1);

  // Re-runs every stored step with a new linearization bias (after the bias moved too far
  // for the first-order correction).
  void reintegrate(const ImuBias& new_bias);

  // Everything an inertial factor needs, without the stored samples.
  PreintegratedImu summary() const;

  // Deltas at the linearization bias.
  const SO3& delta_R() const { return dR_; }
  const Vec3& delta_v() const { return dv_; }
  const Vec3& delta_p() const { return dp_; }
  double dt() const { return dt_; }
  const Mat9& covariance() const { return cov_; }
  const ImuBias& bias() const { return bias_; }
  const ImuNoise& noise() const { return noise_; }
  std::size_t steps() const { return steps_.size(); }
  std::size_t skipped_steps() const { return skipped_; }

  // Bias Jacobians of the deltas.
  const Mat3& dR_dbg() const { return J_R_bg_; }
  const Mat3& dv_dbg() const { return J_v_bg_; }
  const Mat3& dv_dba() const { return J_v_ba_; }
  const Mat3& dp_dbg() const { return J_p_bg_; }
  const Mat3& dp_dba() const { return J_p_ba_; }

  // First-order corrections to another bias, without re-integrating.
  SO3 corrected_delta_R(const Vec3& bg) const;
  Vec3 corrected_delta_v(const Vec3& bg, const Vec3& ba) const;
  Vec3 corrected_delta_p(const Vec3& bg, const Vec3& ba) const;

  // State at the end of the interval from the state at its start; `gravity` is the world
  // gravity vector (e.g. (0, 0, -9.81)). The second form corrects the deltas to `bias`.
  NavState predict(const NavState& i, const Vec3& gravity) const;
  NavState predict(const NavState& i, const Vec3& gravity, const ImuBias& bias) const;

 private:
  struct Step {
    ImuSample a, b;
  };
  void reset();
  void propagate(const ImuSample& a, const ImuSample& b);

  ImuBias bias_;
  ImuNoise noise_;
  std::vector<Step> steps_;
  std::size_t skipped_ = 0;

  SO3 dR_;
  Vec3 dv_ = Vec3::Zero();
  Vec3 dp_ = Vec3::Zero();
  double dt_ = 0.0;
  Mat9 cov_ = Mat9::Zero();
  Mat3 J_R_bg_ = Mat3::Zero();
  Mat3 J_v_bg_ = Mat3::Zero();
  Mat3 J_v_ba_ = Mat3::Zero();
  Mat3 J_p_bg_ = Mat3::Zero();
  Mat3 J_p_ba_ = Mat3::Zero();
};

}  // namespace kestrel::imu
