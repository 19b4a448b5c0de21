#pragma once
// PnP with RANSAC (OpenCV's solvePnPRansac on undistorted pixels), for when there is no usable
// motion prior: first frames after a loss, relocalization.
#include <cstdint>
#include <optional>
#include <vector>

#include "core/camera.hpp"
#include "core/se3.hpp"

namespace kestrel::tracking {

struct PnpOptions {
  int iterations = 200;
  double reprojection_px = 4.0;
  double confidence = 0.99;
  int min_inliers = 12;
};

struct PnpResult {
  SE3 T_c_w;
  std::vector<std::uint8_t> inlier;
  int inliers = 0;
};

// nullopt when there are too few correspondences, RANSAC fails, or the pose is not finite.
std::optional<PnpResult> solve_pnp_ransac(const PinholeCamera& camera,
                                          const std::vector<Vec3>& points_w,
                                          const std::vector<Vec2>& uv_undistorted,
                                          const PnpOptions& options = {});

}  // namespace kestrel::tracking
