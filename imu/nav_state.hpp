#pragma once
// The inertial state that pre-integration predicts and the IMU factor constrains.
#include "core/eigen_types.hpp"
#include "core/so3.hpp"

namespace kestrel::imu {

// Additive sensor biases: measured = true + bias.
struct ImuBias {
  Vec3 gyro = Vec3::Zero();  // rad/s
  Vec3 acc = Vec3::Zero();   // m/s^2
};

// Body (IMU) state in the world: R_w_b, p_w_b and the world-frame velocity of the body.
struct NavState {
  SO3 R;
  Vec3 p = Vec3::Zero();
  Vec3 v = Vec3::Zero();
};

// Gravity in a z-up world.
constexpr double kGravityMagnitude = 9.81;
inline Vec3 gravity_vector() { return Vec3(0.0, 0.0, -kGravityMagnitude); }

}  // namespace kestrel::imu
