#include "tracking/pnp.hpp"

#include <opencv2/calib3d.hpp>

namespace kestrel::tracking {

std::optional<PnpResult> solve_pnp_ransac(const PinholeCamera& camera,
                                          const std::vector<Vec3>& points_w,
                                          const std::vector<Vec2>& uv, const PnpOptions& options) {
  const std::size_t n = points_w.size();
  if (n != uv.size() || static_cast<int>(n) < std::max(options.min_inliers, 6)) return std::nullopt;
  std::vector<cv::Point3d> obj(n);
  std::vector<cv::Point2d> img(n);
  for (std::size_t i = 0; i < n; ++i) {
    obj[i] = cv::Point3d(points_w[i].x(), points_w[i].y(), points_w[i].z());
    img[i] = cv::Point2d(uv[i].x(), uv[i].y());
  }
  const cv::Matx33d K(camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1);
  cv::Mat rvec, tvec;
  std::vector<int> inliers;
  bool ok = false;
  try {
    ok = cv::solvePnPRansac(obj, img, K, cv::noArray(), rvec, tvec, false, options.iterations,
                            static_cast<float>(options.reprojection_px), options.confidence,
                            inliers, cv::SOLVEPNP_EPNP);
  } catch (const cv::Exception&) {
    return std::nullopt;  // degenerate configurations throw inside OpenCV's minimal solvers
  }
  if (!ok || static_cast<int>(inliers.size()) < options.min_inliers) return std::nullopt;
  const Vec3 w(rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2));
  const Vec3 t(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
  if (!w.allFinite() || !t.allFinite()) return std::nullopt;
  PnpResult r;
  r.T_c_w = SE3(SO3::exp(w), t);
  r.inlier.assign(n, 0);
  for (int i : inliers) r.inlier[static_cast<std::size_t>(i)] = 1;
  r.inliers = static_cast<int>(inliers.size());
  return r;
}

}  // namespace kestrel::tracking
