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

// Linear interpolation of two samples at time t (t0 <= t <= t1); how IMU data is brought to
// frame stamps.
ImuSample interpolate(const ImuSample& a, const ImuSample& b, Timestamp t);

}  // namespace kestrel
