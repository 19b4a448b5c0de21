#pragma once
// Motion-only bundle adjustment: the camera pose that best reprojects known world points onto
// their (undistorted) keypoints and, where the frame reads depth, puts them at that depth.
// Gauss-Newton on SE(3) with a Huber kernel, analytic Jacobian and ORB-SLAM's four rounds of
// outlier classification. No OpenCV, no Ceres: it runs every frame and must be cheap.
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
  double depth = 0;       // the frame's own depth at the pixel, metres; 0: none
};

struct PoseOptimizerOptions {
  int rounds = 4;
  int iterations = 10;          // Gauss-Newton steps per round
  double chi2_outlier = 5.991;  // chi-square 95% with 2 dof, in units of the pixel variance
  // An observation with depth adds the disparity of a virtual stereo rig, bf / z in pixels, as
  // a third residual (ORB-SLAM's RGB-D pose optimization): the frame's own depth then pins the
  // translation along each ray, which reprojection alone leaves to the map points' placement.
  // The Tracker uses its local BA's rig (mapping::LocalBaOptions::virtual_bf). 0: reprojection
  // only.
  double virtual_bf = 0.0;
  double chi2_outlier_depth = 7.815;  // the same test with the disparity (3 dof)
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
