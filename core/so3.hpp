#pragma once
// SO(3) on unit quaternions, with the exponential map, its inverse and the left/right
// Jacobians that IMU pre-integration and on-manifold optimization need (Forster et al. 2017,
// Barfoot 2017). Sophus is not packaged in Debian 12, so this small header is our own.
#include <cmath>

#include "core/eigen_types.hpp"

namespace kestrel {

class SO3 {
 public:
  // Below this angle the closed forms lose precision and Taylor series take over.
  static constexpr double kSmallAngle = 1e-6;

  SO3() : q_(Quat::Identity()) {}
  explicit SO3(const Quat& q) : q_(q.normalized()) {}
  explicit SO3(const Mat3& R) : q_(Quat(R).normalized()) {}

  static SO3 exp(const Vec3& w) {
    const double theta2 = w.squaredNorm();
    const double theta = std::sqrt(theta2);
    double real = 0.0;
    double imag_factor = 0.0;
    if (theta < kSmallAngle) {
      real = 1.0 - theta2 / 8.0;
      imag_factor = 0.5 - theta2 / 48.0;
    } else {
      real = std::cos(0.5 * theta);
      imag_factor = std::sin(0.5 * theta) / theta;
    }
    return SO3(Quat(real, imag_factor * w.x(), imag_factor * w.y(), imag_factor * w.z()));
  }

  // Rotation vector with angle in [0, pi].
  Vec3 log() const {
    Quat q = q_;
    if (q.w() < 0.0) q.coeffs() = -q.coeffs();
    const Vec3 v = q.vec();
    const double n = v.norm();
    if (n < kSmallAngle) {
      // atan2(n, w) / n ~ 1/w (1 - n^2 / (3 w^2))
      return (2.0 / q.w()) * (1.0 - n * n / (3.0 * q.w() * q.w())) * v;
    }
    return (2.0 * std::atan2(n, q.w()) / n) * v;
  }

  static Mat3 hat(const Vec3& v) {
    Mat3 m;
    m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
    return m;
  }
  static Vec3 vee(const Mat3& m) { return Vec3(m(2, 1), m(0, 2), m(1, 0)); }

  // exp(w + d) ~ exp(w) exp(Jr(w) d)
  static Mat3 right_jacobian(const Vec3& w) { return left_jacobian(-w); }
  static Mat3 right_jacobian_inverse(const Vec3& w) { return left_jacobian_inverse(-w); }
  // exp(w + d) ~ exp(Jl(w) d) exp(w)
  static Mat3 left_jacobian(const Vec3& w) {
    const double theta2 = w.squaredNorm();
    const Mat3 W = hat(w);
    if (theta2 < kSmallAngle * kSmallAngle * 1e4) {
      return Mat3::Identity() + 0.5 * W + (1.0 / 6.0 - theta2 / 120.0) * W * W;
    }
    const double theta = std::sqrt(theta2);
    return Mat3::Identity() + ((1.0 - std::cos(theta)) / theta2) * W +
           ((theta - std::sin(theta)) / (theta2 * theta)) * W * W;
  }
  static Mat3 left_jacobian_inverse(const Vec3& w) {
    const double theta2 = w.squaredNorm();
    const Mat3 W = hat(w);
    if (theta2 < kSmallAngle * kSmallAngle * 1e4) {
      return Mat3::Identity() - 0.5 * W + (1.0 / 12.0 + theta2 / 720.0) * W * W;
    }
    const double theta = std::sqrt(theta2);
    const double coeff = 1.0 / theta2 - (1.0 + std::cos(theta)) / (2.0 * theta * std::sin(theta));
    return Mat3::Identity() - 0.5 * W + coeff * W * W;
  }

  Mat3 matrix() const { return q_.toRotationMatrix(); }
  const Quat& quaternion() const { return q_; }
  SO3 inverse() const { return SO3(q_.conjugate()); }
  double angle() const { return log().norm(); }
  Mat3 adjoint() const { return matrix(); }

  SO3 operator*(const SO3& other) const { return SO3(q_ * other.q_); }
  Vec3 operator*(const Vec3& p) const { return q_ * p; }

 private:
  Quat q_;
};

}  // namespace kestrel
