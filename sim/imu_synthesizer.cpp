#include "sim/imu_synthesizer.hpp"

#include <cmath>

namespace kestrel::sim {

ImuSynthesizer::ImuSynthesizer(const ImuNoise& noise, std::uint64_t seed, bool with_noise)
    : noise_(noise), with_noise_(with_noise), rng_(seed) {}

ImuSample ImuSynthesizer::ideal(const BodyState& s, Timestamp t) {
  ImuSample out;
  out.t = t;
  out.gyro = s.omega_b;
  out.acc = s.T_w_b.so3().inverse() * (s.a_w + Vec3(0.0, 0.0, kGravity));
  return out;
}

Vec3 ImuSynthesizer::gaussian3(double sigma) {
  const double x = normal_(rng_), y = normal_(rng_), z = normal_(rng_);
  return sigma * Vec3(x, y, z);
}

ImuSample ImuSynthesizer::sample(const BodyState& s, Timestamp t) {
  ImuSample out = ideal(s, t);
  if (!with_noise_) return out;
  const double rate = noise_.rate_hz;
  const double dt = 1.0 / rate;
  // Discrete white noise sigma_d = sigma_c * sqrt(rate); random walk step sigma_c * sqrt(dt).
  out.gyro += gyro_bias_ + gaussian3(noise_.gyro_noise * std::sqrt(rate));
  out.acc += acc_bias_ + gaussian3(noise_.acc_noise * std::sqrt(rate));
  gyro_bias_ += gaussian3(noise_.gyro_walk * std::sqrt(dt));
  acc_bias_ += gaussian3(noise_.acc_walk * std::sqrt(dt));
  return out;
}

}  // namespace kestrel::sim
