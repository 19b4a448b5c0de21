#pragma once
// Simulated IMU: exact readings from the analytic trajectory, plus white noise and bias random
// walks from the continuous-time densities of core ImuNoise (discretized at the sample rate).
#include <cstdint>
#include <random>

#include "core/imu.hpp"
#include "sim/spline_trajectory.hpp"

namespace kestrel::sim {

// World gravity (z up), m/s^2.
inline constexpr double kGravity = 9.81;

class ImuSynthesizer {
 public:
  ImuSynthesizer(const ImuNoise& noise, std::uint64_t seed, bool with_noise);

  // Reading at the body state s, stamped t. Calls must come in time order at the configured
  // rate: each one advances the bias random walk by one step.
  ImuSample sample(const BodyState& s, Timestamp t);

  const Vec3& gyro_bias() const { return gyro_bias_; }
  const Vec3& acc_bias() const { return acc_bias_; }

  // The noise-free specific force and rate for a state (what the test integrates).
  static ImuSample ideal(const BodyState& s, Timestamp t);

 private:
  Vec3 gaussian3(double sigma);

  ImuNoise noise_;
  bool with_noise_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  Vec3 gyro_bias_ = Vec3::Zero();
  Vec3 acc_bias_ = Vec3::Zero();
};

}  // namespace kestrel::sim
