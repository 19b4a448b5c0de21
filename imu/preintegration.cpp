#include "imu/preintegration.hpp"

#include <algorithm>
#include <cmath>

namespace kestrel::imu {
namespace {

// The sample at time t: interpolated between neighbours, or the nearest one held constant
// when t lies outside the samples.
ImuSample sample_at(std::span<const ImuSample> samples, Timestamp t) {
  const auto it = std::lower_bound(samples.begin(), samples.end(), t,
                                   [](const ImuSample& s, Timestamp v) { return s.t < v; });
  ImuSample out;
  if (it == samples.begin()) {
    out = samples.front();
  } else if (it == samples.end()) {
    out = samples.back();
  } else if (it->t == t) {
    out = *it;
  } else {
    out = interpolate(*(it - 1), *it, t);
  }
  out.t = t;
  return out;
}

bool finite_sample(const ImuSample& s) { return s.gyro.allFinite() && s.acc.allFinite(); }

}  // namespace

void Preintegration::reset() {
  dR_ = SO3();
  dv_.setZero();
  dp_.setZero();
  dt_ = 0.0;
  cov_.setZero();
  J_R_bg_.setZero();
  J_v_bg_.setZero();
  J_v_ba_.setZero();
  J_p_bg_.setZero();
  J_p_ba_.setZero();
}

void Preintegration::integrate(const ImuSample& a, const ImuSample& b) {
  if (b.t <= a.t || !finite_sample(a) || !finite_sample(b)) {
    ++skipped_;
    return;
  }
  steps_.push_back({a, b});
  propagate(a, b);
}

bool Preintegration::integrate(std::span<const ImuSample> samples, Timestamp t0, Timestamp t1) {
  if (samples.empty() || t1 < t0) return false;
  if (t1 == t0) return samples.front().t <= t0 && samples.back().t >= t1;
  const bool covered = samples.front().t <= t0 && samples.back().t >= t1;

  ImuSample prev = sample_at(samples, t0);
  for (const ImuSample& s : samples) {
    if (s.t <= t0) continue;
    if (s.t >= t1) break;
    integrate(prev, s);
    prev = s;
  }
  integrate(prev, sample_at(samples, t1));
  return covered;
}

void Preintegration::reintegrate(const ImuBias& new_bias) {
  bias_ = new_bias;
  reset();
  for (const Step& s : steps_) propagate(s.a, s.b);
}

void Preintegration::propagate(const ImuSample& a, const ImuSample& b) {
  const double h = to_seconds(b.t - a.t);
  const Vec3 w = 0.5 * (a.gyro + b.gyro) - bias_.gyro;
  const Vec3 a0 = a.acc - bias_.acc;
  const Vec3 a1 = b.acc - bias_.acc;

  const Vec3 wh = w * h;
  const SO3 dR_step = SO3::exp(wh);
  const Mat3 dR_step_T = dR_step.matrix().transpose();
  const Mat3 Jr = SO3::right_jacobian(wh);
  const Mat3 R0 = dR_.matrix();
  const SO3 dR_next = dR_ * dR_step;
  const Mat3 R1 = dR_next.matrix();

  // Specific force in the start frame, trapezoid over the step.
  const Vec3 acc = 0.5 * (R0 * a0 + R1 * a1);

  // Linearization of `acc` in the rotation error at the step start, the gyro bias and the
  // accelerometer bias (the end rotation depends on both the start error and the gyro).
  const Mat3 R1_a1_hat = R1 * SO3::hat(a1);
  const Mat3 A_phi = -0.5 * (R0 * SO3::hat(a0) + R1_a1_hat * dR_step_T);
  const Mat3 A_bg = 0.5 * h * R1_a1_hat * Jr;
  const Mat3 A_ba = -0.5 * (R0 + R1);

  // Bias Jacobians (the old values feed the new ones, so velocity/position go first).
  const Mat3 dacc_dbg = A_phi * J_R_bg_ + A_bg;
  J_p_bg_ += h * J_v_bg_ + 0.5 * h * h * dacc_dbg;
  J_p_ba_ += h * J_v_ba_ + 0.5 * h * h * A_ba;
  J_v_bg_ += h * dacc_dbg;
  J_v_ba_ += h * A_ba;
  J_R_bg_ = dR_step_T * J_R_bg_ - h * Jr;

  // Covariance: the averaged gyro and accelerometer noise of the step, each white with the
  // discrete density sigma / sqrt(h), so that the sum over steps matches the continuous model.
  Mat9 A = Mat9::Identity();
  A.block<3, 3>(0, 0) = dR_step_T;
  A.block<3, 3>(3, 0) = h * A_phi;
  A.block<3, 3>(6, 0) = 0.5 * h * h * A_phi;
  A.block<3, 3>(6, 3) = h * Mat3::Identity();
  Eigen::Matrix<double, 9, 6> B = Eigen::Matrix<double, 9, 6>::Zero();
  B.block<3, 3>(0, 0) = -h * Jr;
  B.block<3, 3>(3, 0) = h * A_bg;
  B.block<3, 3>(6, 0) = 0.5 * h * h * A_bg;
  B.block<3, 3>(3, 3) = h * A_ba;
  B.block<3, 3>(6, 3) = 0.5 * h * h * A_ba;
  const double var_g = noise_.gyro_noise * noise_.gyro_noise / h;
  const double var_a = noise_.acc_noise * noise_.acc_noise / h;
  Eigen::Matrix<double, 6, 1> q;
  q << var_g, var_g, var_g, var_a, var_a, var_a;
  cov_ = A * cov_ * A.transpose() + B * q.asDiagonal() * B.transpose();

  dp_ += dv_ * h + 0.5 * h * h * acc;
  dv_ += h * acc;
  dR_ = dR_next;
  dt_ += h;
}

PreintegratedImu Preintegration::summary() const {
  PreintegratedImu s;
  s.delta_R = dR_.matrix();
  s.delta_v = dv_;
  s.delta_p = dp_;
  s.dt = dt_;
  s.bias_gyro = bias_.gyro;
  s.bias_acc = bias_.acc;
  s.dR_dbg = J_R_bg_;
  s.dv_dbg = J_v_bg_;
  s.dv_dba = J_v_ba_;
  s.dp_dbg = J_p_bg_;
  s.dp_dba = J_p_ba_;
  s.covariance = cov_;
  return s;
}

SO3 Preintegration::corrected_delta_R(const Vec3& bg) const {
  return dR_ * SO3::exp(J_R_bg_ * (bg - bias_.gyro));
}

Vec3 Preintegration::corrected_delta_v(const Vec3& bg, const Vec3& ba) const {
  return dv_ + J_v_bg_ * (bg - bias_.gyro) + J_v_ba_ * (ba - bias_.acc);
}

Vec3 Preintegration::corrected_delta_p(const Vec3& bg, const Vec3& ba) const {
  return dp_ + J_p_bg_ * (bg - bias_.gyro) + J_p_ba_ * (ba - bias_.acc);
}

NavState Preintegration::predict(const NavState& i, const Vec3& gravity) const {
  return predict(i, gravity, bias_);
}

NavState Preintegration::predict(const NavState& i, const Vec3& gravity,
                                 const ImuBias& bias) const {
  NavState j;
  j.R = i.R * corrected_delta_R(bias.gyro);
  j.v = i.v + gravity * dt_ + (i.R * corrected_delta_v(bias.gyro, bias.acc));
  j.p =
      i.p + i.v * dt_ + 0.5 * gravity * dt_ * dt_ + (i.R * corrected_delta_p(bias.gyro, bias.acc));
  return j;
}

}  // namespace kestrel::imu
