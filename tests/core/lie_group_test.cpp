#include <gtest/gtest.h>
#include <rapidcheck.h>

#include <cmath>

#include "core/se3.hpp"

namespace kestrel {
namespace {

// Rotation vectors with angles over (0, pi) plus the tiny angles where Taylor forms apply, from
// the first case on: inRange scales with the test's size, which would hold the first cases near
// each range's low end (angles of 3 rad about one axis).
rc::Gen<Vec3> gen_rotation_vector() {
  return rc::gen::map(
      rc::gen::resize(100,
                      rc::gen::tuple(rc::gen::inRange(-1000, 1001), rc::gen::inRange(-1000, 1001),
                                     rc::gen::inRange(-1000, 1001), rc::gen::inRange(0, 4))),
      [](const std::tuple<int, int, int, int>& v) {
        Vec3 axis(std::get<0>(v), std::get<1>(v), std::get<2>(v));
        if (axis.norm() < 1e-9) axis = Vec3::UnitX();
        const double scales[4] = {3.0, 1.0, 1e-3, 1e-9};
        const double angle = std::min(scales[std::get<3>(v)] * axis.norm() / 1732.0, 3.1);
        return Vec3(axis.normalized() * angle);
      });
}

rc::Gen<Vec6> gen_twist() {
  return rc::gen::map(
      rc::gen::tuple(gen_rotation_vector(), rc::gen::resize(100, rc::gen::inRange(-5000, 5001)),
                     rc::gen::resize(100, rc::gen::inRange(-5000, 5001)),
                     rc::gen::resize(100, rc::gen::inRange(-5000, 5001))),
      [](const std::tuple<Vec3, int, int, int>& v) {
        Vec6 xi;
        xi << std::get<1>(v) * 1e-3, std::get<2>(v) * 1e-3, std::get<3>(v) * 1e-3, std::get<0>(v);
        return xi;
      });
}

double rot_distance(const SO3& a, const SO3& b) { return (a.inverse() * b).log().norm(); }

TEST(LieGroup, So3ExpLogRoundTrip) {
  EXPECT_TRUE(rc::check("log(exp(w)) == w", [] {
    const Vec3 w = *gen_rotation_vector();
    RC_ASSERT((SO3::exp(w).log() - w).norm() <= 1e-9 * std::max(1.0, w.norm()));
  }));
  EXPECT_TRUE(rc::check("exp(log(R)) == R", [] {
    const SO3 R = SO3::exp(*gen_rotation_vector());
    RC_ASSERT(rot_distance(SO3::exp(R.log()), R) < 1e-10);
  }));
}

TEST(LieGroup, So3MatchesAngleAxis) {
  const Vec3 w(0.3, -1.2, 0.7);
  const Mat3 expected = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
  EXPECT_LT((SO3::exp(w).matrix() - expected).norm(), 1e-12);
  EXPECT_LT((SO3::hat(w) * Vec3(1, 2, 3) - w.cross(Vec3(1, 2, 3))).norm(), 1e-15);
  EXPECT_LT((SO3::vee(SO3::hat(w)) - w).norm(), 0.0 + 1e-15);
}

TEST(LieGroup, So3NearPi) {
  const Vec3 w = Vec3(1, 2, 2).normalized() * (M_PI - 1e-7);
  EXPECT_LT((SO3::exp(w).log() - w).norm(), 1e-6);
  EXPECT_TRUE(SO3::exp(Vec3(M_PI, 0, 0)).log().allFinite());
}

// Numeric right Jacobian: exp(w)^-1 exp(w + h e_i) ~ exp(Jr e_i h).
Mat3 numeric_so3_right_jacobian(const Vec3& w) {
  Mat3 J;
  const double h = 1e-6;
  for (int i = 0; i < 3; ++i) {
    const Vec3 d = Vec3::Unit(i) * h;
    const Vec3 plus = (SO3::exp(w).inverse() * SO3::exp(w + d)).log();
    const Vec3 minus = (SO3::exp(w).inverse() * SO3::exp(w - d)).log();
    J.col(i) = (plus - minus) / (2 * h);
  }
  return J;
}

TEST(LieGroup, So3JacobiansMatchNumeric) {
  EXPECT_TRUE(rc::check("Jr numeric", [] {
    const Vec3 w = *gen_rotation_vector();
    RC_PRE(w.norm() < 3.0);
    const Mat3 Jr = SO3::right_jacobian(w);
    RC_ASSERT((Jr - numeric_so3_right_jacobian(w)).norm() < 1e-6);
    RC_ASSERT((Jr * SO3::right_jacobian_inverse(w) - Mat3::Identity()).norm() < 1e-9);
    RC_ASSERT((SO3::left_jacobian(w) - SO3::exp(w).matrix() * Jr).norm() < 1e-9);
  }));
}

TEST(LieGroup, Se3ExpLogRoundTrip) {
  EXPECT_TRUE(rc::check("log(exp(xi)) == xi", [] {
    const Vec6 xi = *gen_twist();
    RC_ASSERT((SE3::exp(xi).log() - xi).norm() <= 1e-8 * std::max(1.0, xi.norm()));
  }));
}

TEST(LieGroup, Se3GroupLaws) {
  EXPECT_TRUE(rc::check("inverse, composition, adjoint", [] {
    const SE3 a = SE3::exp(*gen_twist());
    const SE3 b = SE3::exp(*gen_twist());
    const Vec6 xi = *gen_twist();
    RC_ASSERT(((a * a.inverse()).matrix() - Mat4::Identity()).norm() < 1e-9);
    RC_ASSERT(((a * b).matrix() - a.matrix() * b.matrix()).norm() < 1e-9);
    const Vec3 p(0.5, -2.0, 3.0);
    RC_ASSERT(((a * p) - (a.matrix() * p.homogeneous()).head<3>()).norm() < 1e-9);
    // Ad(T) xi = log(T exp(xi) T^-1)
    const Vec6 lhs = a.adjoint() * xi;
    const SE3 conj = a * SE3::exp(xi) * a.inverse();
    RC_ASSERT((SE3::exp(lhs).matrix() - conj.matrix()).norm() < 1e-8);
  }));
}

TEST(LieGroup, Se3JacobiansMatchNumeric) {
  EXPECT_TRUE(rc::check("Jl and Jr numeric", [] {
    const Vec6 xi = *gen_twist();
    RC_PRE(xi.tail<3>().norm() < 3.0);
    const double h = 1e-6;
    Mat6 Jl_num, Jr_num;
    const SE3 T = SE3::exp(xi);
    for (int i = 0; i < 6; ++i) {
      const Vec6 d = Vec6::Unit(i) * h;
      Jl_num.col(i) =
          ((SE3::exp(xi + d) * T.inverse()).log() - (SE3::exp(xi - d) * T.inverse()).log()) /
          (2 * h);
      Jr_num.col(i) =
          ((T.inverse() * SE3::exp(xi + d)).log() - (T.inverse() * SE3::exp(xi - d)).log()) /
          (2 * h);
    }
    RC_ASSERT((SE3::left_jacobian(xi) - Jl_num).norm() < 1e-5);
    RC_ASSERT((SE3::right_jacobian(xi) - Jr_num).norm() < 1e-5);
    RC_ASSERT((SE3::left_jacobian(xi) * SE3::left_jacobian_inverse(xi) - Mat6::Identity()).norm() <
              1e-8);
  }));
}

TEST(LieGroup, TinyAnglesStayFinite) {
  for (double a : {0.0, 1e-300, 1e-12, 1e-7, 1e-5}) {
    const Vec3 w(a, -a, 0.5 * a);
    EXPECT_TRUE(SO3::exp(w).log().allFinite());
    EXPECT_TRUE(SO3::right_jacobian(w).allFinite());
    EXPECT_TRUE(SO3::right_jacobian_inverse(w).allFinite());
    Vec6 xi;
    xi << 1, 2, 3, w;
    EXPECT_TRUE(SE3::exp(xi).log().allFinite());
    EXPECT_TRUE(SE3::left_jacobian(xi).allFinite());
  }
}

}  // namespace
}  // namespace kestrel
