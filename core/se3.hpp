#pragma once
// SE(3) as (SO3, translation). Tangent vectors are ordered [rho (translation); phi (rotation)],
// as in Sophus and Barfoot. Naming follows DESIGN.md: T_a_b maps points from frame b to a.
#include "core/so3.hpp"

namespace kestrel {

class SE3 {
 public:
  SE3() : t_(Vec3::Zero()) {}
  SE3(const SO3& R, const Vec3& t) : R_(R), t_(t) {}
  SE3(const Quat& q, const Vec3& t) : R_(q), t_(t) {}
  explicit SE3(const Mat4& m) : R_(Mat3(m.topLeftCorner<3, 3>())), t_(m.topRightCorner<3, 1>()) {}

  static SE3 exp(const Vec6& xi) {
    const Vec3 rho = xi.head<3>();
    const Vec3 phi = xi.tail<3>();
    return SE3(SO3::exp(phi), SO3::left_jacobian(phi) * rho);
  }
  Vec6 log() const {
    const Vec3 phi = R_.log();
    Vec6 xi;
    xi << SO3::left_jacobian_inverse(phi) * t_, phi;
    return xi;
  }

  static Mat4 hat(const Vec6& xi) {
    Mat4 m = Mat4::Zero();
    m.topLeftCorner<3, 3>() = SO3::hat(xi.tail<3>());
    m.topRightCorner<3, 1>() = xi.head<3>();
    return m;
  }

  // Ad(T) xi = log(T exp(xi) T^-1)
  Mat6 adjoint() const {
    Mat6 a = Mat6::Zero();
    const Mat3 R = R_.matrix();
    a.topLeftCorner<3, 3>() = R;
    a.topRightCorner<3, 3>() = SO3::hat(t_) * R;
    a.bottomRightCorner<3, 3>() = R;
    return a;
  }

  // exp(xi + d) ~ exp(Jl(xi) d) exp(xi)   (Barfoot, eq. 7.85)
  static Mat6 left_jacobian(const Vec6& xi) {
    const Vec3 phi = xi.tail<3>();
    const Mat3 Jl = SO3::left_jacobian(phi);
    Mat6 J = Mat6::Zero();
    J.topLeftCorner<3, 3>() = Jl;
    J.bottomRightCorner<3, 3>() = Jl;
    J.topRightCorner<3, 3>() = q_matrix(xi.head<3>(), phi);
    return J;
  }
  static Mat6 left_jacobian_inverse(const Vec6& xi) {
    const Vec3 phi = xi.tail<3>();
    const Mat3 Jl_inv = SO3::left_jacobian_inverse(phi);
    Mat6 J = Mat6::Zero();
    J.topLeftCorner<3, 3>() = Jl_inv;
    J.bottomRightCorner<3, 3>() = Jl_inv;
    J.topRightCorner<3, 3>() = -Jl_inv * q_matrix(xi.head<3>(), phi) * Jl_inv;
    return J;
  }
  // exp(xi + d) ~ exp(xi) exp(Jr(xi) d)
  static Mat6 right_jacobian(const Vec6& xi) { return left_jacobian(-xi); }
  static Mat6 right_jacobian_inverse(const Vec6& xi) { return left_jacobian_inverse(-xi); }

  const SO3& so3() const { return R_; }
  Mat3 rotation() const { return R_.matrix(); }
  const Vec3& translation() const { return t_; }
  Vec3& translation() { return t_; }
  const Quat& quaternion() const { return R_.quaternion(); }
  Mat4 matrix() const {
    Mat4 m = Mat4::Identity();
    m.topLeftCorner<3, 3>() = R_.matrix();
    m.topRightCorner<3, 1>() = t_;
    return m;
  }

  SE3 inverse() const {
    const SO3 Ri = R_.inverse();
    return SE3(Ri, -(Ri * t_));
  }
  SE3 operator*(const SE3& o) const { return SE3(R_ * o.R_, R_ * o.t_ + t_); }
  Vec3 operator*(const Vec3& p) const { return R_ * p + t_; }

  bool is_finite() const { return t_.allFinite() && R_.quaternion().coeffs().allFinite(); }

 private:
  // The coupling block of the SE(3) Jacobian (Barfoot's Q), with its Taylor form near zero.
  static Mat3 q_matrix(const Vec3& rho, const Vec3& phi) {
    const Mat3 P = SO3::hat(phi);
    const Mat3 Rh = SO3::hat(rho);
    const double theta2 = phi.squaredNorm();
    double c1 = 0.0, c2 = 0.0, c3 = 0.0;
    if (theta2 < 1e-6) {
      c1 = 1.0 / 6.0 - theta2 / 120.0;
      c2 = 1.0 / 24.0 - theta2 / 720.0;
      c3 = 1.0 / 120.0 - theta2 / 2520.0;
    } else {
      const double theta = std::sqrt(theta2);
      const double s = std::sin(theta);
      const double c = std::cos(theta);
      c1 = (theta - s) / (theta2 * theta);
      c2 = (theta2 + 2.0 * c - 2.0) / (2.0 * theta2 * theta2);
      c3 = (2.0 * theta - 3.0 * s + theta * c) / (2.0 * theta2 * theta2 * theta);
    }
    const Mat3 PR = P * Rh;
    const Mat3 RP = Rh * P;
    const Mat3 PRP = PR * P;
    return 0.5 * Rh + c1 * (PR + RP + PRP) + c2 * (P * PR + RP * P - 3.0 * PRP) +
           c3 * (PRP * P + P * PRP);
  }

  SO3 R_;
  Vec3 t_;
};

}  // namespace kestrel
