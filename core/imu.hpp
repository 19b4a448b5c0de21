#pragma once
#include "core/eigen_types.hpp"
#include "core/timestamp.hpp"

namespace kestrel {

// One IMU reading in the IMU (body) frame: angular rate [rad/s], specific force [m/s^2].
struct ImuSample {
  Timestamp t = 0;
  Vec3 gyro = Vec3::Zero();
  Vec3 acc = Vec3::Zero();
};

// Continuous-time noise densities, as in Kalibr / EuRoC sensor.yaml and ORB-SLAM3 settings.
struct ImuNoise {
  double gyro_noise = 1.7e-4;  // rad/s/sqrt(Hz)
  double acc_noise = 2.0e-3;   // m/s^2/sqrt(Hz)
  double gyro_walk = 1.9e-5;   // rad/s^2/sqrt(Hz)
  double acc_walk = 3.0e-3;    // m/s^3/sqrt(Hz)
  double rate_hz = 200.0;
};

// The outcome of pre-integrating the IMU between two stamps (imu::Preintegration), as plain
// data that a keyframe can carry and an optimizer can turn into an inertial factor: the deltas
// at the linearization biases, their bias Jacobians and the 9x9 covariance ordered
// [δφ, δv, δp] (Forster et al. 2017).
struct PreintegratedImu {
  Mat3 delta_R = Mat3::Identity();
  Vec3 delta_v = Vec3::Zero();
  Vec3 delta_p = Vec3::Zero();
  double dt = 0.0;  // seconds
  Vec3 bias_gyro = Vec3::Zero();
  Vec3 bias_acc = Vec3::Zero();
  Mat3 dR_dbg = Mat3::Zero();
  Mat3 dv_dbg = Mat3::Zero();
  Mat3 dv_dba = Mat3::Zero();
  Mat3 dp_dbg = Mat3::Zero();
  Mat3 dp_dba = Mat3::Zero();
  Eigen::Matrix<double, 9, 9> covariance = Eigen::Matrix<double, 9, 9>::Zero();
};

// Linear interpolation of two samples at time t (t0 <= t <= t1); how IMU data is brought to
// frame stamps.
ImuSample interpolate(const ImuSample& a, const ImuSample& b, Timestamp t);

}  // namespace kestrel
