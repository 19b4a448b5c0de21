#pragma once
// A smooth analytic body trajectory and its exact IMU readings, for pre-integration and
// initialization tests: R(t) = Exp(θ(t)), p(t) sinusoids; ω_b = Jr(θ) θ̇ and
// f_b = Rᵀ (p̈ − g), so the readings are exact (no finite differences).
#include <cmath>
#include <random>
#include <vector>

#include "core/imu.hpp"
#include "core/so3.hpp"
#include "imu/nav_state.hpp"

namespace kestrel::imu::test {

struct Motion {
  // Amplitudes large enough to exercise rotation/velocity coupling (about 1 rad/s, 3 m/s^2).
  double rot_scale = 1.0;
  double pos_scale = 1.0;
  Vec3 gyro_bias = Vec3::Zero();
  Vec3 acc_bias = Vec3::Zero();
  Vec3 gravity = gravity_vector();

  Vec3 theta(double t) const {
    return rot_scale * Vec3(0.3 * std::sin(1.1 * t), 0.2 * std::sin(0.7 * t + 0.5),
                            0.5 * std::sin(0.9 * t + 1.0));
  }
  Vec3 theta_dot(double t) const {
    return rot_scale * Vec3(0.33 * std::cos(1.1 * t), 0.14 * std::cos(0.7 * t + 0.5),
                            0.45 * std::cos(0.9 * t + 1.0));
  }
  Vec3 position(double t) const {
    return pos_scale *
           Vec3(2.0 * std::sin(0.8 * t), 1.5 * std::cos(0.6 * t), 0.5 * std::sin(1.2 * t));
  }
  Vec3 velocity(double t) const {
    return pos_scale *
           Vec3(1.6 * std::cos(0.8 * t), -0.9 * std::sin(0.6 * t), 0.6 * std::cos(1.2 * t));
  }
  Vec3 acceleration(double t) const {
    return pos_scale *
           Vec3(-1.28 * std::sin(0.8 * t), -0.54 * std::cos(0.6 * t), -0.72 * std::sin(1.2 * t));
  }
  SO3 rotation(double t) const { return SO3::exp(theta(t)); }
  NavState state(double t) const { return {rotation(t), position(t), velocity(t)}; }

  Vec3 true_gyro(double t) const { return SO3::right_jacobian(theta(t)) * theta_dot(t); }
  Vec3 true_acc(double t) const { return rotation(t).inverse() * (acceleration(t) - gravity); }
  ImuSample sample(double t) const {
    ImuSample s;
    s.t = from_seconds(t);
    s.gyro = true_gyro(t) + gyro_bias;
    s.acc = true_acc(t) + acc_bias;
    return s;
  }
  // Samples at rate_hz covering [t0, t1] (inclusive, on the grid k / rate_hz).
  std::vector<ImuSample> samples(double t0, double t1, double rate_hz) const {
    std::vector<ImuSample> out;
    const long k0 = static_cast<long>(std::floor(t0 * rate_hz));
    const long k1 = static_cast<long>(std::ceil(t1 * rate_hz));
    for (long k = k0; k <= k1; ++k) out.push_back(sample(static_cast<double>(k) / rate_hz));
    return out;
  }
};

// Adds white noise with the discrete densities sigma / sqrt(dt) of `noise`.
inline void add_noise(std::vector<ImuSample>& samples, const ImuNoise& noise, double dt,
                      std::mt19937& rng) {
  std::normal_distribution<double> n01(0.0, 1.0);
  const double sg = noise.gyro_noise / std::sqrt(dt);
  const double sa = noise.acc_noise / std::sqrt(dt);
  for (ImuSample& s : samples) {
    for (int k = 0; k < 3; ++k) {
      s.gyro(k) += sg * n01(rng);
      s.acc(k) += sa * n01(rng);
    }
  }
}

}  // namespace kestrel::imu::test
