#include "eval/alignment.hpp"

#include "eval/pose_error.hpp"

namespace kestrel::eval {

const char* alignment_name(Alignment alignment) {
  switch (alignment) {
    case Alignment::kNone:
      return "none";
    case Alignment::kSe3:
      return "SE(3)";
    case Alignment::kSim3:
      return "Sim(3)";
  }
  return "?";
}

std::optional<Similarity> estimate_alignment(const std::vector<Mat4>& ref,
                                             const std::vector<Mat4>& est, bool with_scale) {
  const Eigen::Index n = static_cast<Eigen::Index>(std::min(ref.size(), est.size()));
  Eigen::Matrix3Xd x(3, n);
  Eigen::Matrix3Xd y(3, n);
  for (Eigen::Index k = 0; k < n; ++k) {
    x.col(k) = est[static_cast<std::size_t>(k)].topRightCorner<3, 1>();
    y.col(k) = ref[static_cast<std::size_t>(k)].topRightCorner<3, 1>();
  }
  return umeyama_alignment(x, y, with_scale);
}

void apply_alignment(std::vector<Mat4>& est, const Similarity& similarity) {
  Mat4 transform = Mat4::Identity();
  transform.topLeftCorner<3, 3>() = similarity.rotation;
  transform.topRightCorner<3, 1>() = similarity.translation;
  for (Mat4& pose : est) {
    if (similarity.scale != 1.0) pose.topRightCorner<3, 1>() *= similarity.scale;
    pose = transform * pose;
  }
}

Mat4 align_origin(std::vector<Mat4>& est, const std::vector<Mat4>& ref) {
  if (est.empty() || ref.empty()) return Mat4::Identity();
  const Mat4 to_ref_origin = ref.front() * se3_inverse(est.front());
  for (Mat4& pose : est) pose = to_ref_origin * pose;
  return to_ref_origin;
}

}  // namespace kestrel::eval
