#include "eval/umeyama.hpp"

#include <Eigen/SVD>
#include <limits>

namespace kestrel::eval {

std::optional<Similarity> umeyama_alignment(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& y,
                                            bool with_scale) {
  const Eigen::Index n = x.cols();
  if (n == 0 || y.cols() != n) return std::nullopt;
  const double inv_n = 1.0 / static_cast<double>(n);

  // Means, eq. 34 and 35; variance of x, eq. 36.
  const Vec3 mean_x = x.rowwise().sum() * inv_n;
  const Vec3 mean_y = y.rowwise().sum() * inv_n;
  const Eigen::Matrix3Xd xc = x.colwise() - mean_x;
  const Eigen::Matrix3Xd yc = y.colwise() - mean_y;
  const double sigma_x = inv_n * xc.squaredNorm();

  // Covariance, eq. 38.
  Mat3 outer_sum = Mat3::Zero();
  for (Eigen::Index i = 0; i < n; ++i) outer_sum += yc.col(i) * xc.col(i).transpose();
  const Mat3 cov_xy = inv_n * outer_sum;

  const Eigen::JacobiSVD<Mat3> svd(cov_xy, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Vec3 d = svd.singularValues();
  int rank = 0;
  for (int k = 0; k < 3; ++k) rank += d(k) > std::numeric_limits<double>::epsilon() ? 1 : 0;
  if (rank < 2) return std::nullopt;

  // S, eq. 43: keep a right-handed frame (Kabsch).
  Mat3 s = Mat3::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) s(2, 2) = -1.0;

  Similarity result;
  result.rotation = svd.matrixU() * s * svd.matrixV().transpose();                   // eq. 40
  result.scale = with_scale ? (1.0 / sigma_x) * (d.asDiagonal() * s).trace() : 1.0;  // eq. 42
  result.translation = mean_y - result.scale * (result.rotation * mean_x);           // eq. 41
  return result;
}

}  // namespace kestrel::eval
