#pragma once
// Motion-only bundle adjustment: the camera pose that best reprojects known world points onto
// their (undistorted) keypoints. Gauss-Newton on SE(3) with a Huber kernel, analytic Jacobian
// and ORB-SLAM's four rounds of outlier classification. No OpenCV, no Ceres: it runs every
// frame and must be cheap.
#include <cstdint>
#include <vector>

#include "core/camera.hpp"
#include "core/reprojection.hpp"
#include "core/se3.hpp"

namespace kestrel::tracking {

using kestrel::pose_residual;  // core/reprojection.hpp

struct PoseObservation {
  Vec3 p_w;               // world point
  Vec2 uv;                // undistorted pixel
  double inv_sigma2 = 1;  // information of the pixel (1 / level_sigma2)
};

struct PoseOptimizerOptions {
  int rounds = 4;
  int iterations = 10;          // Gauss-Newton steps per round
  double chi2_outlier = 5.991;  // chi-square 95% with 2 dof, in units of the pixel variance
  int min_inliers = 10;
};

// A prior on the pose from outside vision (the IMU's prediction): residual log(T T_prior⁻¹)
// in the same left-perturbation tangent space, weighted by `information` ([rho; phi] order).
// With many good points the points decide; with few or bad ones (a dark corridor, a close
// wall) the prior keeps the pose where the IMU says it is.
struct PosePrior {
  SE3 T_c_w;
  Mat6 information = Mat6::Zero();
};

struct PoseOptimizerResult {
  SE3 T_c_w;
  std::vector<std::uint8_t> inlier;  // per observation
  int inliers = 0;
  bool ok = false;  // finite pose with at least min_inliers inliers
};

PoseOptimizerResult optimize_pose(const PinholeCamera& camera,
                                  const std::vector<PoseObservation>& observations,
                                  const SE3& T_c_w_initial,
                                  const PoseOptimizerOptions& options = {},
                                  const PosePrior* prior = nullptr);

}  // namespace kestrel::tracking
