#pragma once
// The reprojection residual of a known point under a camera pose, with its Jacobian for the
// left perturbation: the one building block of every pose-only least-squares fit (tracking's
// motion-only BA, the dynamic filter's ego-motion refinement).
#include "core/camera.hpp"
#include "core/eigen_types.hpp"
#include "core/se3.hpp"

namespace kestrel {

using Mat26 = Eigen::Matrix<double, 2, 6>;

// Residual r = project(T_c_w * p_w) - uv of the undistorted pinhole (distortion ignored) and,
// when J is given, dr/d(delta) for the left perturbation T_c_w <- exp(delta) * T_c_w,
// delta = [rho; phi]. False when the point is behind the camera.
bool pose_residual(const PinholeCamera& camera, const SE3& T_c_w, const Vec3& p_w, const Vec2& uv,
                   Vec2* r, Mat26* J = nullptr);

}  // namespace kestrel
