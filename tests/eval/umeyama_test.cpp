// Property tests: Umeyama recovers an exact similarity (Sim(3)) or rigid motion (SE(3)).
#include "eval/umeyama.hpp"

#include <gtest/gtest.h>
#include <rapidcheck.h>

#include <Eigen/SVD>

#include "eval/alignment.hpp"

namespace kestrel::eval {
namespace {

// Doubles in [lo, hi] from integers, so rapidcheck can shrink them.
rc::Gen<double> real_in(double lo, double hi) {
  // Over the whole interval from the first case (inRange alone scales with the test's size).
  return rc::gen::map(rc::gen::resize(100, rc::gen::inRange(0, 1000001)),
                      [lo, hi](int k) { return lo + (hi - lo) * static_cast<double>(k) / 1e6; });
}

Mat3 random_rotation() {
  const double w = *real_in(-1.0, 1.0);
  const double x = *real_in(-1.0, 1.0);
  const double y = *real_in(-1.0, 1.0);
  const double z = *real_in(-1.0, 1.0);
  Quat q(w, x, y, z);
  RC_PRE(q.norm() > 0.1);
  return q.normalized().toRotationMatrix();
}

Eigen::Matrix3Xd random_points() {
  const int n = *rc::gen::inRange(4, 40);
  Eigen::Matrix3Xd x(3, n);
  for (int i = 0; i < n; ++i) {
    for (int r = 0; r < 3; ++r) x(r, i) = *real_in(-20.0, 20.0);
  }
  // Well spread in at least two directions, or the rotation is not determined.
  const Eigen::Matrix3Xd centered = x.colwise() - x.rowwise().mean();
  const Eigen::JacobiSVD<Mat3> svd(centered * centered.transpose() / n);
  RC_PRE(svd.singularValues()(1) > 1.0);
  return x;
}

TEST(Umeyama, RecoversRandomSimilarity) {
  EXPECT_TRUE(rc::check("Sim(3) Umeyama recovers s, R, t exactly", [] {
    const Eigen::Matrix3Xd x = random_points();
    const Mat3 R = random_rotation();
    const Vec3 t(*real_in(-50.0, 50.0), *real_in(-50.0, 50.0), *real_in(-50.0, 50.0));
    const double s = *real_in(0.05, 20.0);
    const Eigen::Matrix3Xd y = (s * R * x).colwise() + t;
    const auto sim = umeyama_alignment(x, y, true);
    RC_ASSERT(sim.has_value());
    RC_ASSERT((sim->rotation - R).cwiseAbs().maxCoeff() < 1e-9);
    RC_ASSERT(std::abs(sim->scale - s) < 1e-9 * s);
    RC_ASSERT((sim->translation - t).norm() < 1e-8 * (1.0 + t.norm() + s * 40.0));
  }));
}

TEST(Umeyama, RecoversRandomRigidMotion) {
  EXPECT_TRUE(rc::check("SE(3) Umeyama recovers R, t exactly", [] {
    const Eigen::Matrix3Xd x = random_points();
    const Mat3 R = random_rotation();
    const Vec3 t(*real_in(-50.0, 50.0), *real_in(-50.0, 50.0), *real_in(-50.0, 50.0));
    const Eigen::Matrix3Xd y = (R * x).colwise() + t;
    const auto se3 = umeyama_alignment(x, y, false);
    RC_ASSERT(se3.has_value());
    RC_ASSERT(se3->scale == 1.0);
    RC_ASSERT((se3->rotation - R).cwiseAbs().maxCoeff() < 1e-9);
    RC_ASSERT((se3->translation - t).norm() < 1e-8 * (1.0 + t.norm()));
    // Applied to poses, the estimate lands on the reference.
    std::vector<Mat4> est(static_cast<std::size_t>(x.cols()), Mat4::Identity());
    std::vector<Mat4> ref = est;
    for (Eigen::Index i = 0; i < x.cols(); ++i) {
      est[static_cast<std::size_t>(i)].topRightCorner<3, 1>() = x.col(i);
      ref[static_cast<std::size_t>(i)].topRightCorner<3, 1>() = y.col(i);
    }
    apply_alignment(est, *se3);
    for (std::size_t i = 0; i < est.size(); ++i) {
      RC_ASSERT((est[i].topRightCorner<3, 1>() - ref[i].topRightCorner<3, 1>()).norm() < 1e-8);
    }
  }));
}

TEST(Umeyama, RejectsCollinearPoints) {
  Eigen::Matrix3Xd x(3, 5);
  for (int i = 0; i < 5; ++i) x.col(i) = Vec3(i, 2.0 * i, -i);
  EXPECT_FALSE(umeyama_alignment(x, x, true).has_value());
}

TEST(Umeyama, MirrorIsNotARotation) {
  // y is x mirrored: the best proper rotation is found (det +1), never a reflection.
  Eigen::Matrix3Xd x(3, 4);
  x << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  Eigen::Matrix3Xd y = x;
  y.row(2) *= -1.0;
  const auto sim = umeyama_alignment(x, y, false);
  ASSERT_TRUE(sim.has_value());
  EXPECT_NEAR(sim->rotation.determinant(), 1.0, 1e-12);
}

}  // namespace
}  // namespace kestrel::eval
