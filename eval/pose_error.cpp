#include "eval/pose_error.hpp"

#include <cmath>
#include <numbers>

namespace kestrel::eval {
namespace {

double error_of(const Mat4& E, PoseRelation relation) {
  switch (relation) {
    case PoseRelation::kTranslation:
      return E.topRightCorner<3, 1>().norm();
    case PoseRelation::kAngleRad:
      return rotation_angle(E.topLeftCorner<3, 3>());
    case PoseRelation::kAngleDeg:
      return rotation_angle(E.topLeftCorner<3, 3>()) * 180.0 / std::numbers::pi;
    case PoseRelation::kFull:
      return (E - Mat4::Identity()).norm();
    case PoseRelation::kRotationPart:
      return (E.topLeftCorner<3, 3>() - Mat3::Identity()).norm();
  }
  return 0.0;
}

}  // namespace

const char* relation_name(PoseRelation relation) {
  switch (relation) {
    case PoseRelation::kTranslation:
      return "translation part";
    case PoseRelation::kAngleRad:
      return "rotation angle in radians";
    case PoseRelation::kAngleDeg:
      return "rotation angle in degrees";
    case PoseRelation::kFull:
      return "full transformation";
    case PoseRelation::kRotationPart:
      return "rotation part";
  }
  return "?";
}

const char* relation_unit(PoseRelation relation) {
  switch (relation) {
    case PoseRelation::kTranslation:
      return "m";
    case PoseRelation::kAngleRad:
      return "rad";
    case PoseRelation::kAngleDeg:
      return "deg";
    case PoseRelation::kFull:
    case PoseRelation::kRotationPart:
      return "";
  }
  return "";
}

Mat4 se3_inverse(const Mat4& pose) {
  Mat4 inv = Mat4::Identity();
  const Mat3 r_inv = pose.topLeftCorner<3, 3>().transpose();
  inv.topLeftCorner<3, 3>() = r_inv;
  inv.topRightCorner<3, 1>() = -(r_inv * pose.topRightCorner<3, 1>());
  return inv;
}

double rotation_angle(const Mat3& m) {
  // scipy Rotation.from_matrix: pick the largest of (m00, m11, m22, trace) to build the
  // quaternion stably, normalize, then as_rotvec's angle 2 atan2(|v|, |w|).
  const double decision[4] = {m(0, 0), m(1, 1), m(2, 2), m.trace()};
  int choice = 0;
  for (int k = 1; k < 4; ++k) {
    if (decision[k] > decision[choice]) choice = k;
  }
  double q[4];  // x y z w
  if (choice != 3) {
    const int i = choice, j = (i + 1) % 3, k = (j + 1) % 3;
    q[i] = 1.0 - decision[3] + 2.0 * m(i, i);
    q[j] = m(j, i) + m(i, j);
    q[k] = m(k, i) + m(i, k);
    q[3] = m(k, j) - m(j, k);
  } else {
    q[0] = m(2, 1) - m(1, 2);
    q[1] = m(0, 2) - m(2, 0);
    q[2] = m(1, 0) - m(0, 1);
    q[3] = 1.0 + decision[3];
  }
  const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  const double v = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]) / norm;
  const double w = std::abs(q[3]) / norm;
  return 2.0 * std::atan2(v, w);
}

std::vector<double> ape_errors(const std::vector<Mat4>& ref, const std::vector<Mat4>& est,
                               PoseRelation relation) {
  std::vector<double> errors;
  errors.reserve(ref.size());
  for (std::size_t k = 0; k < ref.size() && k < est.size(); ++k) {
    if (relation == PoseRelation::kTranslation) {
      errors.push_back((est[k].topRightCorner<3, 1>() - ref[k].topRightCorner<3, 1>()).norm());
    } else {
      errors.push_back(error_of(se3_inverse(est[k]) * ref[k], relation));
    }
  }
  return errors;
}

std::vector<double> rpe_errors(const std::vector<Mat4>& ref, const std::vector<Mat4>& est,
                               const IdPairs& pairs, PoseRelation relation) {
  std::vector<double> errors;
  errors.reserve(pairs.size());
  for (const auto& [i, j] : pairs) {
    const Mat4 q_rel = se3_inverse(ref[i]) * ref[j];
    const Mat4 p_rel = se3_inverse(est[i]) * est[j];
    errors.push_back(error_of(se3_inverse(q_rel) * p_rel, relation));
  }
  return errors;
}

}  // namespace kestrel::eval
