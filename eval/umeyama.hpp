#pragma once
// Least-squares similarity between two registered point sets (Umeyama, PAMI 1991), written to
// do exactly what evo's geometry.umeyama_alignment does, so that aligned errors match evo.
#include <optional>

#include "core/eigen_types.hpp"

namespace kestrel::eval {

// y ~ scale * rotation * x + translation
struct Similarity {
  Mat3 rotation = Mat3::Identity();
  Vec3 translation = Vec3::Zero();
  double scale = 1.0;

  Vec3 operator*(const Vec3& p) const { return scale * (rotation * p) + translation; }
};

// x: estimate positions (3xn), y: reference positions (3xn). With with_scale false the scale
// stays 1 (SE(3) alignment). nullopt when the covariance has rank < 2 (fewer than three
// non-collinear points), where the rotation is not determined.
std::optional<Similarity> umeyama_alignment(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& y,
                                            bool with_scale);

}  // namespace kestrel::eval
