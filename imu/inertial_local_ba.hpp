#pragma once
// Visual-inertial local bundle adjustment (ORB-SLAM3's local inertial BA, with one bias pair for
// the window): mapping::solve_local_ba's reprojection and depth terms plus, between consecutive
// keyframes of the window, the IMU's pre-integration (imu::ImuFactor) on the keyframes' body
// poses and velocities. Vision alone lets a keyframe taken from a few dozen look-alike matches (a
// dark wall, a crowd) sit centimetres off; the accelerometer says how far the body can have moved
// since the keyframe before it, and at what speed, independently of anything seen.
#include <ceres/sized_cost_function.h>

#include "core/camera.hpp"
#include "imu/imu_factor.hpp"
#include "mapping/local_ba.hpp"

namespace kestrel::imu {

// ImuFactor on the camera poses that local BA optimizes (blocks xi = log T_c_w, perturbed on
// the left), the body velocities and the biases, in ImuFactor's order [xi_i, v_i, bg, ba, xi_j,
// v_j].
class CameraImuFactor final : public ceres::SizedCostFunction<9, 6, 3, 3, 3, 6, 3> {
 public:
  CameraImuFactor(const PreintegratedImu& pre, const Vec3& gravity, const SE3& T_body_camera);
  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override;

 private:
  ImuFactor factor_;
  SE3 T_c_b_;
  Mat6 d_xi_;
};

struct InertialBaOptions {
  // The window shares one pair of biases, held near the pre-integrations' own (the inertial
  // predictor's estimate) by these sigmas.
  double gyro_bias_sigma = 0.005;  // rad/s
  double acc_bias_sigma = 0.05;    // m/s^2
  // Added to the pre-integration's own covariance, which knows only the sensor's white noise:
  // what the model leaves out (the camera-IMU calibration, timing, the biases' drift within
  // the window) is the same kind of floor that the gyro links carry (SystemOptions).
  double rotation_floor_rad = 1e-4;
  double rotation_relative = 0.005;  // of the angle turned
  double velocity_floor = 0.01;      // m/s
  double position_floor = 0.003;     // m
};

// The problem's inertial edges (mapping::LocalBaOptions::inertial) become factors. Every
// velocity the edges join is estimated, even at a fixed keyframe (its pose anchors the window,
// its velocity from the IMU's prediction is no better than the others); solution.v_w has the
// optimized keyframes'. Without edges this is exactly mapping::solve_local_ba.
mapping::LocalBaSolution solve_inertial_local_ba(const mapping::LocalBaProblem& problem,
                                                 const PinholeCamera& camera,
                                                 const mapping::LocalBaOptions& options = {},
                                                 const InertialBaOptions& inertial = {});

}  // namespace kestrel::imu
