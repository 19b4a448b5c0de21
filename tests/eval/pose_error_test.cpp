#include "eval/pose_error.hpp"

#include <gtest/gtest.h>

#include <numbers>

namespace kestrel::eval {
namespace {

Mat4 pose(const Vec3& axis, double angle, const Vec3& t) {
  Mat4 m = Mat4::Identity();
  m.topLeftCorner<3, 3>() = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  m.topRightCorner<3, 1>() = t;
  return m;
}

TEST(PoseError, RotationAngleOverWholeRange) {
  for (const double angle : {0.0, 1e-9, 0.3, 1.5, 3.0, std::numbers::pi - 1e-7}) {
    const Mat4 m = pose(Vec3(1, -2, 0.5), angle, Vec3::Zero());
    EXPECT_NEAR(rotation_angle(m.topLeftCorner<3, 3>()), angle, 1e-12) << angle;
  }
}

TEST(PoseError, ApeRelations) {
  const std::vector<Mat4> ref = {pose(Vec3::UnitZ(), 0.0, Vec3(1, 2, 3))};
  const std::vector<Mat4> est = {pose(Vec3::UnitZ(), 0.25, Vec3(1, 2, 5))};
  EXPECT_DOUBLE_EQ(ape_errors(ref, est, PoseRelation::kTranslation)[0], 2.0);
  EXPECT_NEAR(ape_errors(ref, est, PoseRelation::kAngleRad)[0], 0.25, 1e-14);
  EXPECT_NEAR(ape_errors(ref, est, PoseRelation::kAngleDeg)[0], 0.25 * 180.0 / std::numbers::pi,
              1e-12);
  // |E - I|_F with E = est^-1 ref: rotation block 2 sqrt(2) sin-ish terms plus the translation.
  const Mat4 E = se3_inverse(est[0]) * ref[0];
  EXPECT_NEAR(ape_errors(ref, est, PoseRelation::kFull)[0], (E - Mat4::Identity()).norm(), 1e-15);
  EXPECT_NEAR(ape_errors(ref, est, PoseRelation::kRotationPart)[0],
              std::sqrt(2.0 * (2.0 - 2.0 * std::cos(0.25))), 1e-14);
}

TEST(PoseError, RpeIgnoresAGlobalOffsetButSeesDrift) {
  // The estimate is the reference moved rigidly: no relative error at all...
  const Mat4 offset = pose(Vec3(0, 1, 1), 0.7, Vec3(5, -3, 2));
  std::vector<Mat4> ref, est, drifted;
  for (int k = 0; k < 5; ++k) {
    ref.push_back(pose(Vec3::UnitZ(), 0.1 * k, Vec3(k, 0.5 * k, 0)));
    est.push_back(offset * ref.back());
    drifted.push_back(ref.back());
    drifted.back()(0, 3) *= 1.1;  // ...while a 10% scale drift along x shows up.
  }
  const IdPairs pairs = filter_pairs_by_index(5, 1, false);
  for (const double e : rpe_errors(ref, est, pairs, PoseRelation::kTranslation)) {
    EXPECT_NEAR(e, 0.0, 1e-12);
  }
  for (const double e : rpe_errors(ref, drifted, pairs, PoseRelation::kTranslation)) {
    EXPECT_NEAR(e, 0.1, 1e-12);
  }
}

}  // namespace
}  // namespace kestrel::eval
